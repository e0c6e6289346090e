#!/usr/bin/env python3
"""The environment seen directly, against Mitsuba 3: a close-up view of the background only.

A 256 x 256 view (60 degree field of view) of `scenes/envmaps/studio.exr` (512 x 256, a few
image pixels per map texel) is rendered by the project's `reference` tool and by Mitsuba 3.
Both interpolate the map bilinearly (docs/conventions.md, "Environment maps"), so the images
must agree to the noise of their pixel-footprint sampling; a nearest-texel lookup is blocky and
differs by 7 % relative L2 here, which the bound below fails. The scene holds one tiny
triangle far behind the camera (a bake config needs geometry), so every pixel sees the sky.

Run by tests/mitsuba/run.sh (which builds the binaries and provides the pinned Mitsuba).
`--plant nearest` replaces the project's image by a nearest-texel lookup of the same map
computed here, to show that the check fails for it.
"""

import argparse
import math
import os
import subprocess
import sys

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "scenes"))
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import generate  # noqa: E402
import mitsuba as mi  # noqa: E402

mi.set_variant("scalar_rgb")
from compare import mitsuba_rows  # noqa: E402  (the row refinement Mitsuba's layout needs)

SIZE, FOV, SPP = 256, 60.0, 64
EYE, TARGET = (0.0, 0.0, 0.0), (0.3, 0.25, -1.0)   # towards the studio's bright lamp side
BOUND = 0.02   # relative L2; measured 0.0036 (bilinear) and 0.071 (nearest texel)


def read_exr(path):
    return np.array(mi.Bitmap(path), dtype=np.float64)[..., :3]


def project_render(work, bins, env):
    g = generate.Gltf()
    mat = g.material("speck", (0.5, 0.5, 0.5))
    m = generate.MeshData()
    # A 1 mm triangle 100 m behind the eye: never in view, never in the way.
    for v in [(0, 0, 100), (0.001, 0, 100), (0, 0.001, 100)]:
        m.vertex(v, (0, 0, 1))
    m.indices = [0, 1, 2]
    g.node("speck", mesh=g.mesh("speck", [(m, mat, True)]))
    g.camera("camera", EYE, TARGET, FOV)
    g.write_gltf(work, "speck")
    cfg = os.path.join(work, "speck.toml")
    with open(cfg, "w") as f:
        f.write('scene = "speck.gltf"\nwidth = %d\nheight = %d\nspp = %d\nreflections = 1\n'
                % (SIZE, SIZE, SPP))
    out = os.path.join(work, "project.exr")
    cmd = [os.path.join(bins, "reference"), cfg, "--env", env, "--out", out,
           "--camera", "eye=%g,%g,%g target=%g,%g,%g fov=%g" % (EYE + TARGET + (FOV,))]
    r = subprocess.run(cmd, capture_output=True, text=True)
    if r.returncode != 0:
        sys.exit("FAIL: %s exited with %d:\n%s" % (" ".join(cmd), r.returncode, r.stderr))
    return read_exr(out)


def mitsuba_render(work, env):
    sky = np.maximum(read_exr(env), 0.0)   # the loader clamps negative channels (config.md)
    refined = os.path.join(work, "sky-mitsuba-rows.exr")
    mi.Bitmap(mitsuba_rows(sky).astype(np.float32)).write(refined)
    scene = mi.load_dict({
        "type": "scene",
        "integrator": {"type": "path", "max_depth": 2},
        "sensor": {
            "type": "perspective", "fov_axis": "y", "fov": FOV,
            "to_world": mi.ScalarTransform4f().look_at(origin=EYE, target=TARGET, up=[0, 1, 0]),
            "film": {"type": "hdrfilm", "width": SIZE, "height": SIZE,
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            "sampler": {"type": "independent", "sample_count": SPP},
        },
        "sky": {"type": "envmap", "filename": refined,
                "to_world": mi.ScalarTransform4f().rotate([0, 1, 0], 180.0)},
    })
    return np.array(mi.render(scene, seed=1), dtype=np.float64)[..., :3]


def nearest_render(env):
    """The planted bug: each pixel centre's direction looked up in the nearest texel."""
    sky = np.maximum(read_exr(env), 0.0)
    h, w, _ = sky.shape
    eye, target = np.array(EYE), np.array(TARGET)
    fwd = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(fwd, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, fwd)
    t = math.tan(math.radians(FOV) / 2)
    c = (np.arange(SIZE) + 0.5) / SIZE
    sx = (2 * c[None, :] - 1) * t
    sy = (1 - 2 * c[:, None]) * t
    d = fwd + right * sx[..., None] + up * sy[..., None]
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    u = (np.arctan2(d[..., 0], -d[..., 2]) / (2 * math.pi) + 0.5) % 1.0
    v = np.arccos(np.clip(d[..., 1], -1, 1)) / math.pi
    x = np.minimum((u * w).astype(int), w - 1)
    y = np.minimum((v * h).astype(int), h - 1)
    return sky[y, x]


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release"))
    ap.add_argument("--work", default=os.path.join(ROOT, "target", "mitsuba-work", "background"))
    ap.add_argument("--plant", choices=["none", "nearest"], default="none")
    args = ap.parse_args()
    os.makedirs(args.work, exist_ok=True)
    env = os.path.join(ROOT, "scenes", "envmaps", "studio.exr")
    project = project_render(args.work, args.bin, env)
    if args.plant == "nearest":
        project = nearest_render(env)
    mts = mitsuba_render(args.work, env)
    l2 = float(np.sqrt(((project - mts) ** 2).sum() / (mts ** 2).sum()))
    ok = l2 <= BOUND
    print("background (%dx%d, %g degrees, studio.exr%s): rel. L2 %.4f, bound %.3f  %s"
          % (SIZE, SIZE, FOV, ", PLANTED nearest" if args.plant == "nearest" else "", l2,
             BOUND, "PASS" if ok else "FAIL"))
    if args.plant == "nearest":
        sys.exit(0 if not ok else "FAIL: the planted nearest-texel lookup was not caught")
    sys.exit(0 if ok else 1)


if __name__ == "__main__":
    main()
