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
    """mesh + quadric: the quadric part runs in a second (spawned) process, which says so; both report their
    seconds. The exact predicates go with the quadric pipeline's track (the lighter one)."""
    seconds = warmup.warm_up("mesh", "quadric", progress=True, parallel=True)
    assert list(seconds) == ["mesh", "quadric"] and all(v >= 0 for v in seconds.values())
    assert "quadric compile in a second process" in capsys.readouterr().out
    assert "exact" in warmup.TRACKS[1] and not set(warmup.TRACKS[0]) & set(warmup.TRACKS[1])
    assert set(warmup.TRACKS[0]) | set(warmup.TRACKS[1]) == set(warmup.PARTS)
