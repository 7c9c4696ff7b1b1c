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


def test_the_two_tracks_warm_in_parallel_processes():
    """exact + quadric: the quadric part runs in a second (spawned) process; both report their seconds."""
    seconds = warmup.warm_up("exact", "quadric", progress=False, parallel=True)
    assert list(seconds) == ["exact", "quadric"] and all(v >= 0 for v in seconds.values())
