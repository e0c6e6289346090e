"""Two Python threads rendering two relighters at once get the images they get one after the
other (a render releases the interpreter's lock and shares nothing between relighters)."""

import threading

import numpy as np

import prt
from conftest import SCENES
from test_relight import same_bits


def frames_of(r, k):
    """k frames, each after a different edit."""
    out = []
    for i in range(k):
        if isinstance(r, prt.VertexRelighter):
            r.environment_rotation = 20.0 * i
            r.camera = r.default_camera.orbited(5.0 * i)
        else:
            r.set("tall_box", alpha=0.1 + 0.05 * i)
        out.append(r.render())
    return out


def setup(cornell, vitrine):
    v = prt.open(vitrine)
    v.size = (160, 120)
    v.environment = SCENES / "envmaps" / "studio.exr"
    return [prt.open(cornell), v]


def test_two_threads_render_what_one_does(cornell, vitrine):
    k = 6
    expected = [frames_of(r, k) for r in setup(cornell, vitrine)]
    relighters = setup(cornell, vitrine)
    got = [None, None]
    barrier = threading.Barrier(2)

    def work(i):
        barrier.wait()
        got[i] = frames_of(relighters[i], k)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(2)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for want, have in zip(expected, got):
        assert len(have) == k
        assert all(same_bits(a, b) for a, b in zip(want, have))
    # The frames differ from each other: each edit reached its image.
    assert not any(np.array_equal(a, b) for a, b in zip(expected[1], expected[1][1:]))

