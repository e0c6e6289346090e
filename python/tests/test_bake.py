"""`prt.bake`: progress events on the calling thread, and stopping a bake (the callback
returning False or raising, Ctrl-C) without leaving a file, keeping a per-vertex bake's
checkpoint."""

import os
import signal
import threading

import pytest

import prt
from conftest import SCENES


def test_progress_events_and_summary(work):
    events, threads = [], set()

    def record(event):
        events.append(event)
        threads.add(threading.get_ident())

    out = work / "furnace.prtbake"
    summary = prt.bake(SCENES / "furnace", out=out, width=32, height=24, spp=2, progress=record)
    assert summary["output"] == str(out) and out.stat().st_size == summary["file_bytes"]
    # Every event on the calling thread, in order: a note, then the bake stage's start, its
    # steps (one per image row) summing to its total, and its finish.
    assert threads == {threading.get_ident()}
    kinds = [e.kind for e in events]
    assert kinds[0] == "note" and "allocation" in events[0].text
    start = kinds.index("start")
    assert events[start].stage == "baking" and events[start].total == 24
    steps = events[start + 1 : -1]
    assert {e.kind for e in steps} == {"advance"} and sum(e.steps for e in steps) == 24
    assert [e.done for e in steps] == sorted(e.done for e in steps)
    assert events[-1].kind == "finish" and events[-1].done == 24
    prt.open(out)


def stop_at_first_step(answer):
    """A callback that lets everything pass until the first step, then answers `answer` (or
    raises it, if it is an exception)."""

    def callback(event):
        if event.kind == "advance":
            if isinstance(answer, BaseException):
                raise answer
            return answer
        return None

    return callback


class Stop(Exception):
    pass


@pytest.mark.parametrize("how", ["false", "raise"])
def test_stopped_pixel_bake_leaves_no_file(work, how):
    out = work / f"stopped-{how}.prtbake"
    if how == "false":
        with pytest.raises(prt.Cancelled, match="returned False"):
            prt.bake(SCENES / "furnace", out=out, width=256, height=256, spp=16,
                     progress=stop_at_first_step(False))
    else:
        with pytest.raises(Stop):
            prt.bake(SCENES / "furnace", out=out, width=256, height=256, spp=16,
                     progress=stop_at_first_step(Stop()))
    assert not out.exists()
    assert not [p for p in work.iterdir() if p.name.startswith(f"stopped-{how}")]


def test_ctrl_c_stops_a_bake(work):
    """A real SIGINT while the bake runs (the calling thread waits in Rust): the bake stops,
    KeyboardInterrupt is raised, nothing is written."""
    out = work / "interrupted.prtbake"
    sent = []

    def interrupt_once(event):
        if event.kind == "advance" and not sent:
            sent.append(True)
            threading.Timer(0.01, os.kill, (os.getpid(), signal.SIGINT)).start()

    # Seconds of work (16 spp took a third of a second: on a loaded machine the timer's thread
    # could run after the bake had finished); the signal stops it within milliseconds.
    with pytest.raises(KeyboardInterrupt):
        prt.bake(SCENES / "furnace", out=out, width=256, height=256, spp=512,
                 progress=interrupt_once)
    assert sent and not out.exists()


def test_stopped_vertex_bake_keeps_its_checkpoint(work):
    out = work / "vitrine-stopped.prtbake"
    seen = []

    def stop_while_baking_vertices(event):
        seen.append(event)
        if event.kind == "advance" and event.stage == "baking vertices":
            return False
        return None

    with pytest.raises(prt.Cancelled):
        prt.bake(SCENES / "vitrine", out=out, spp=4, progress=stop_while_baking_vertices)
    assert not out.exists()
    checkpoint = work / "vitrine-stopped.prtbake.partial"
    assert checkpoint.is_dir() and any(checkpoint.iterdir())
    # The warning about the sky map's negative texels reached the callback.
    assert any(e.kind == "warning" and "sky.exr" in e.text for e in seen)


def test_warnings_without_a_callback_are_python_warnings(work, tmp_path):
    config = tmp_path / "bake.toml"
    config.write_text(
        f'scene = "{SCENES / "furnace" / "furnace.glb"}"\nwidth = 8\nheight = 8\nspp = 1\n'
        f'[environment]\nmap = "{SCENES / "envmaps" / "sky.exr"}"\n'
    )
    with pytest.warns(prt.PrtWarning, match="sky.exr: 11 texel"):
        prt.bake(config, out=tmp_path / "warned.prtbake")
