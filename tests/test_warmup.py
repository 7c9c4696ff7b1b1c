"""csgnb.warmup: runs the workloads it names, refuses parts it does not know."""

import pytest

from csgnb import warmup


def test_warm_up_returns_the_seconds_per_part():
    seconds = warmup.warm_up("quadric", progress=False)
    assert list(seconds) == ["quadric"] and seconds["quadric"] >= 0


def test_unknown_parts_are_named_in_the_error():
    with pytest.raises(ValueError, match=r"\['rendering'\].*exact"):
        warmup.warm_up("exact", "rendering")


def test_command_line_rejects_unknown_parts(capsys):
    with pytest.raises(SystemExit):
        warmup.main(["nope"])
    assert "unknown part" in capsys.readouterr().err


def test_the_two_tracks_warm_in_parallel_processes(capsys):
    """mesh + sampling: the sampling part runs in a second (spawned) process, which says so; both report their
    seconds. The tracks split the parts between them."""
    seconds = warmup.warm_up("mesh", "sampling", progress=True, parallel=True)
    assert list(seconds) == ["mesh", "sampling"] and all(v >= 0 for v in seconds.values())
    assert "sampling compile in a second process" in capsys.readouterr().out
    assert not set(warmup.TRACKS[0]) & set(warmup.TRACKS[1])
    assert set(warmup.TRACKS[0]) | set(warmup.TRACKS[1]) == set(warmup.PARTS)


def test_a_part_that_waits_for_the_other_track_runs_after_it():
    """boundary (second track) waits for extraction (first track), then both report their seconds."""
    assert warmup.WAITS_FOR["boundary"] == "extraction"
    seconds = warmup.warm_up("extraction", "boundary", progress=False, parallel=True)
    assert list(seconds) == ["extraction", "boundary"] and all(v >= 0 for v in seconds.values())


def test_an_error_in_the_first_track_does_not_leave_the_second_waiting(monkeypatch):
    """The waited-for part fails: the error is raised at once, not after the second track's wait limit."""
    import time

    def failing(variants):
        raise RuntimeError("extraction failed")

    monkeypatch.setitem(warmup.PARTS, "extraction", failing)
    t0 = time.perf_counter()
    with pytest.raises(RuntimeError, match="extraction failed"):
        warmup.warm_up("extraction", "boundary", progress=False, parallel=True)
    assert time.perf_counter() - t0 < 0.5 * warmup._WAIT_LIMIT
