#!/usr/bin/env python3
"""Compares the project's relit images with Mitsuba 3 renders of the same scenes.

Every other image test compares the baker with the project's own reference tracer, which
shares the integrator, light sampling, camera and scene loader with it, so a bug there cancels
out. Mitsuba shares nothing: it gets the triangles (exported from the glTF by gltf_scene.py),
the camera, the BRDFs (the mapping in docs/brdf.md, "Matching Mitsuba 3"), the lights and the
environment map file, and renders them with its own path tracer.

For each scene: bake K times (K seeds) and relight every bake with the same material edits;
render Mitsuba K times (K seeds). The spread over the K images of each side gives its
per-pixel noise, so the checks scale with the measured noise instead of a guessed tolerance:

  - means: over the image, each material (the one seen at the pixel centre) and each of 4 x 4
    tiles, per channel: |mean(project) - mean(Mitsuba)| <= Z standard errors + SLACK x mean;
  - rel. L2 of the project's image against Mitsuba's (each the mean of its K): at most what
    the measured noise of both sides explains (the point pure noise exceeds with probability
    L2_ALPHA) plus SLACK.

Run by tests/mitsuba/run.sh (which provides the pinned Mitsuba). `--plant` checks the checks:
it corrupts the project's side (black, 2x bright, +5 %, mirrored, environment turned 90
degrees) and each must fail. Usage:

    tests/mitsuba/run.sh                       # the comparison, as CI runs it
    tests/mitsuba/run.sh --plant all           # every planted bug must be caught
"""

import argparse
import math
import os
import shutil
import subprocess
import sys
import time

import numpy as np

import gltf_scene

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
sys.path.insert(0, os.path.join(ROOT, "scenes"))
import generate  # noqa: E402  (the scene generator's glTF writer and meshes)

import mitsuba as mi  # noqa: E402

# scalar_rgb: plain CPU, no LLVM needed, renders RGB directly (no spectral upsampling), so an
# 'rgb' value means the same linear Rec. 709 triple the project uses.
mi.set_variant("scalar_rgb")

# Bounds, chosen from measurement (docs/conventions.md, "Checked against Mitsuba 3"): with
# independent noise on both sides the z-scores of the means are standard normal and the
# squared-error ratio is about 1.
Z = 4.5            # standard errors allowed on a mean (about 250 tests per run)
SLACK = 0.01       # plus this fraction of the mean (and this rel. L2): systematic differences
                   # we accept, such as the two renderers' readings of the sky's rows (below)
L2_ALPHA = 1e-4    # the rel. L2 bound is the point pure noise exceeds with this probability
MIN_PIXELS = 32    # regions smaller than this are reported but not tested


# ------------------------------------------------------------------------------------------
# The scenes: the project's glTF (or one written here), the bake config's material tables,
# the relight edits, and the sizes. Sizes and sample counts keep the whole run within a few
# minutes on two cores while the noise stays small enough to resolve a 5 % bias.

CASES = {
    # Lambert walls, an area light (which also reflects: its glTF material is diffuse), the
    # GGX tall box, and the bunny relit from GGX to another GGX. Two reflections = Mitsuba
    # max_depth 3.
    "cornell": dict(
        scene="scenes/cornell/cornell.gltf",
        width=96, height=96, reflections=2, replicas=4, bake_spp=128, mitsuba_spp=128,
        materials={
            "bunny": dict(editable=True, family="ggx", kd=[0.55, 0.5, 0.45], ks=0.25,
                          alpha=0.3),
            "tall_box": dict(editable=True, family="ggx", kd=0.5, ks=0.3, alpha=0.15),
        },
        edits={"bunny.kd": [0.7, 0.35, 0.25], "bunny.alpha": 0.4,
               "tall_box.alpha": 0.25, "tall_box.ks": 0.4},
        environment=None,
    ),
    # The gold napkin ring, baked as GGX instead of the scene's Blinn-Phong, on a Lambert
    # floor under a point light: the caustic inside the ring is light reflected by the GGX
    # lobe towards the floor (next-event estimation to a delta light at the second vertex).
    "ring": dict(
        scene="scenes/ring/ring.gltf",
        width=96, height=96, reflections=2, replicas=4, bake_spp=128, mitsuba_spp=128,
        materials={"ring": dict(editable=True, family="ggx", kd=0.02, alpha=0.15)},
        edits={"ring.alpha": 0.2},
        environment=None,
    ),
    # The white furnace (a .glb): a Lambert sphere under a constant environment, relit to a
    # colour. The constant environment is sampled by the cosine, not from a map.
    "furnace": dict(
        scene="scenes/furnace/furnace.glb",
        width=64, height=64, reflections=2, replicas=4, bake_spp=64, mitsuba_spp=64,
        materials={"sphere": dict(editable=True, family="diffuse")},
        edits={"sphere.kd": [0.8, 0.6, 0.3]},
        environment={"color": [1.0, 1.0, 1.0]},
    ),
    # A GGX sphere, a Lambert sphere and a Lambert floor under a lat-long sky with a sun (not
    # in view, so lighting and shadows come from importance-sampled directions) and a warm
    # glow on the +X horizon (so a mirrored or turned map shows). The sky is visible above the
    # floor. Three reflections = Mitsuba max_depth 4.
    "envsphere": dict(
        scene="envsphere/envsphere.gltf",   # written into the work folder by write_envsphere
        generate=True,
        width=96, height=96, reflections=3, replicas=4, bake_spp=128, mitsuba_spp=128,
        materials={
            "floor": dict(editable=True, family="diffuse"),
            "chrome": dict(editable=True, family="ggx", kd=[0.05, 0.1, 0.2]),
        },
        edits={"floor.kd": [0.6, 0.55, 0.45], "chrome.ks": 0.75, "chrome.alpha": 0.3},
        # Turned 90 degrees about +Y by the config ([environment] rotation), so the rotation's
        # sign is checked by a renderer that shares nothing with ours.
        environment={"map": "envsphere/sky.exr", "rotation": 90.0},
    ),
}


# ------------------------------------------------------------------------------------------
# The environment scene (written into the work folder: nothing to commit, a few MB).

SKY_W, SKY_H = 1024, 512  # 0.35 degree texels; the sky's features are 5 degrees and wider


def latlong_directions(width, height):
    """Directions of the texel centres, by the documented convention (docs/conventions.md):
    theta = pi v from +Y, phi = 2 pi (u - 0.5) from -Z, d = (sin t sin p, cos t, -sin t cos p).
    The map is defined as a function of direction through this formula; if the baker read
    maps differently, its lighting would come from elsewhere than Mitsuba's."""
    u = (np.arange(width) + 0.5) / width
    v = (np.arange(height) + 0.5) / height
    theta = math.pi * v[:, None]
    phi = 2 * math.pi * (u[None, :] - 0.5)
    return np.stack([np.sin(theta) * np.sin(phi), np.cos(theta) * np.ones_like(phi),
                     -np.sin(theta) * np.cos(phi)], axis=-1)


def sky_radiance(d):
    """A smooth sky: zenith-to-horizon gradient, a brown ground below a 6-degree blend, a warm
    glow on the +X horizon, and a sun (sigma 5 degrees, peak 60) up and behind on the left."""
    y = d[..., 1:2]
    zenith, horizon = np.array([0.15, 0.3, 0.75]), np.array([0.7, 0.75, 0.8])
    sky = horizon + (zenith - horizon) * np.sqrt(np.clip(y, 0.0, 1.0))
    ground = np.array([0.25, 0.2, 0.15])
    t = np.clip((y + 0.05) / 0.1, 0.0, 1.0)
    t = t * t * (3 - 2 * t)
    rad = ground + (sky - ground) * t

    def lobe(axis, sigma_deg):
        axis = np.asarray(axis, float) / np.linalg.norm(axis)
        ang = np.arccos(np.clip(d @ axis, -1.0, 1.0))
        return np.exp(-0.5 * (ang / math.radians(sigma_deg)) ** 2)[..., None]

    rad = rad + np.array([1.6, 0.8, 0.3]) * lobe([1.0, 0.15, 0.0], 25.0)
    rad = rad + np.array([60.0, 57.0, 50.0]) * lobe([-0.6, 0.65, -0.5], 5.0)
    return rad


def write_envsphere(folder, sky_path, turn_quarter=False):
    """Writes envsphere.gltf/.bin with the project's generator and the sky EXR. With
    turn_quarter the sky is turned 90 degrees about +Y (the planted bug 'envrot90')."""
    os.makedirs(folder, exist_ok=True)
    g = generate.Gltf()
    floor_mat = g.material("floor", (0.5, 0.5, 0.5))                   # diffuse
    chrome_mat = g.material("chrome", (0.9, 0.9, 0.9), metallic=1.0, roughness=0.45)
    clay_mat = g.material("clay", (0.8, 0.3, 0.2))                     # diffuse
    floor = generate.MeshData()
    generate.grid_quad(floor, (-4, 0, 4), (8, 0, 0), (0, 0, -8), 1, 1, (0, 1, 0))
    g.node("floor", mesh=g.mesh("floor", [(floor, floor_mat, True)]))
    verts, indices = generate.icosphere(4)
    for name, mat, centre, r in (("chrome", chrome_mat, (-0.45, 0.5, 0.0), 0.5),
                                 ("clay", clay_mat, (0.55, 0.3, 0.35), 0.3)):
        s = generate.MeshData()
        for v in verts:
            s.vertex(generate.add(generate.mul(v, r), centre), v)
        s.indices = list(indices)
        g.node(name, mesh=g.mesh(name, [(s, mat, True)]))
    g.camera("camera", (0.0, 1.1, 3.2), (0.0, 0.45, 0.0), 35.0)
    g.write_gltf(folder, "envsphere")
    sky = sky_radiance(latlong_directions(SKY_W, SKY_H))
    if turn_quarter:
        sky = np.roll(sky, SKY_W // 4, axis=1)
    mi.Bitmap(sky.astype(np.float32)).write(sky_path)


def mitsuba_rows(sky):
    """The H-row map `sky` (rows centred at v = (j + 0.5) / H, clamped beyond the first and
    last centre, linear in between: docs/conventions.md) as a (2H + 1)-row map for Mitsuba,
    whose row r sits at v = r / (2H): odd rows are the project's rows, even rows the midpoints
    between them, and the pole rows repeat the first and last row. Linear interpolation between
    these rows is the project's interpolation exactly (a linear function sampled at its
    midpoints, and a constant in the pole bands), in u as well since columns are unchanged."""
    h = sky.shape[0]
    out = np.empty((2 * h + 1,) + sky.shape[1:], dtype=np.float64)
    out[1::2] = sky
    out[2:-1:2] = 0.5 * (sky[:-1] + sky[1:])
    out[0] = sky[0]
    out[-1] = sky[-1]
    return out


def mitsuba_rows_file(path):
    """Writes mitsuba_rows of the EXR at `path` beside it; returns the new file's path."""
    refined = os.path.splitext(path)[0] + "-mitsuba-rows.exr"
    sky = np.array(mi.Bitmap(path), dtype=np.float64)[..., :3]
    mi.Bitmap(mitsuba_rows(sky).astype(np.float32)).write(refined)
    return refined


# ------------------------------------------------------------------------------------------
# Materials: the glTF factors mapped as docs/conventions.md says, then the bake config's
# overrides, then the relight edits.

def as_rgb(v):
    return [float(v)] * 3 if np.isscalar(v) else [float(c) for c in v]


def resolve_materials(gltf_materials, config_tables, edits):
    out = {}
    for m in gltf_materials:
        metallic = min(max(m["metallic"], 0.0), 1.0)
        rough = min(max(m["roughness"], 0.0), 1.0)
        base = m["base"]
        if metallic == 0 and rough >= 1:
            b = dict(family="diffuse", kd=list(base), ks=[0.0] * 3, alpha=1.0)
        else:
            b = dict(family="ggx", kd=[c * (1 - metallic) for c in base],
                     ks=[0.04 + (c - 0.04) * metallic for c in base],
                     alpha=max(rough * rough, 1e-4))
        for key, value in config_tables.get(m["name"], {}).items():
            if key in ("kd", "ks"):
                b[key] = as_rgb(value)
            elif key in ("family", "alpha"):
                b[key] = value
        b["emission"] = m["emission"]
        out[m["name"]] = b
    for key, value in edits.items():
        name, param = key.split(".")
        out[name][param] = as_rgb(value) if param in ("kd", "ks") else value
    for name, b in out.items():
        if b["family"] == "diffuse":
            b["ks"] = [0.0] * 3
        elif b["family"] != "ggx":
            sys.exit("%s: family %s has no Mitsuba equivalent (docs/brdf.md)" % (name, b["family"]))
    return out


def mitsuba_bsdf(b):
    """docs/brdf.md, "Matching Mitsuba 3": Kd/pi + Ks D G1 G1 / (4 cos cos) is Mitsuba's
    blendbsdf of `diffuse` (Kd / (1 - w)) and `roughconductor` (ggx, the same alpha,
    material 'none' = Fresnel 1, Ks / w) with weight w = max Ks / (max Kd + max Ks); Mitsuba
    refuses reflectances above 1, which this w avoids whenever max Kd + max Ks <= 1. Twosided,
    because the baker shades both sides of every surface."""
    kd, ks = np.array(b["kd"]), np.array(b["ks"])
    diffuse = lambda r: {"type": "diffuse", "reflectance": {"type": "rgb", "value": list(r)}}
    if ks.max() <= 0:
        inner = diffuse(kd)
    else:
        if kd.max() + ks.max() > 1 + 1e-6:
            sys.exit("max Kd + max Ks > 1: no Mitsuba blend with reflectances <= 1")
        w = ks.max() / (kd.max() + ks.max())
        spec = {"type": "roughconductor", "distribution": "ggx", "alpha": float(b["alpha"]),
                "material": "none",
                # (minimum: only float rounding can take these past 1, given the check above)
                "specular_reflectance": {"type": "rgb", "value": list(np.minimum(ks / w, 1))}}
        inner = spec if kd.max() <= 0 else {"type": "blendbsdf", "weight": float(w),
                                            "diffuse": diffuse(np.minimum(kd / (1 - w), 1)),
                                            "specular": spec}
    return {"type": "twosided", "bsdf": inner}


def check_bsdf_mapping():
    """Mitsuba's BSDF against docs/brdf.md's formula at random direction pairs, so the mapping
    above is checked, not assumed (e.g. that roughconductor uses the separable Smith G1 G1 and
    that material 'none' means Fresnel 1). Returns the largest relative difference."""
    rng = np.random.default_rng(7)
    worst = 0.0
    ctx = mi.BSDFContext()
    for alpha, kd, ks in ((0.3, [0.5, 0.4, 0.3], [0.3, 0.2, 0.5]), (0.05, [0.1, 0.1, 0.1],
                          [0.8, 0.7, 0.6]), (1.0, [0.0, 0.0, 0.0], [0.9, 0.9, 0.9])):
        b = dict(family="ggx", kd=kd, ks=ks, alpha=alpha)
        bsdf = mi.load_dict(mitsuba_bsdf(b))
        for _ in range(100):
            wo, wi = (v / np.linalg.norm(v) for v in np.abs(rng.normal(size=(2, 3))))
            si = mi.SurfaceInteraction3f()
            si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
            si.wi = mi.Vector3f(*wo)
            got = np.array(bsdf.eval(ctx, si, mi.Vector3f(*wi))) / wi[2]
            want = brdf_formula(b, wo, wi)
            worst = max(worst, float(np.max(np.abs(got - want) / want)))
    return worst


def brdf_formula(b, wo, wi):
    """docs/brdf.md: Kd/pi + Ks D(h) G1(wi) G1(wo) / (4 cos_i cos_o), separable Smith."""
    a2 = b["alpha"] ** 2
    h = (wo + wi) / np.linalg.norm(wo + wi)
    ch2 = h[2] ** 2
    d = a2 / (math.pi * (a2 * ch2 + (1 - ch2)) ** 2)
    g1 = lambda c: 2 * c / (c + math.sqrt(a2 + (1 - a2) * c * c))
    return (np.array(b["kd"]) / math.pi
            + np.array(b["ks"]) * d * g1(wi[2]) * g1(wo[2]) / (4 * wi[2] * wo[2]))


# ------------------------------------------------------------------------------------------
# The Mitsuba scene.

def mitsuba_scene(case, gltf_path, env, work):
    doc, buffers = gltf_scene.load(gltf_path)
    mats = resolve_materials(gltf_scene.materials(doc), case["materials"], case["edits"])
    names = [m["name"] for m in gltf_scene.materials(doc)]
    cam = gltf_scene.camera(doc)
    pos, fwd, up = cam["position"], cam["forward"], cam["up"]
    scene = {
        "type": "scene",
        # The baker's `reflections = N` counts surface vertices on a path; Mitsuba's max_depth
        # counts path segments (1 = emitters seen directly), so max_depth = N + 1.
        "integrator": {"type": "path", "max_depth": case["reflections"] + 1},
        "sensor": {
            "type": "perspective",
            "fov_axis": "y",  # the baker's yfov; the aspect ratio is width / height in both
            "fov": math.degrees(cam["yfov"]),
            "near_clip": 1e-3,
            "to_world": mi.ScalarTransform4f().look_at(origin=list(pos),
                                                        target=list(pos + fwd), up=list(up)),
            # The box filter: each sample counts in its own pixel only, as in the baker.
            "film": {"type": "hdrfilm", "width": case["width"], "height": case["height"],
                     "rfilter": {"type": "box"}, "pixel_format": "rgb"},
            # bench/compare may ask for another of Mitsuba's samplers (`--mitsuba-sampler`).
            "sampler": {"type": case.get("sampler", "independent")},
        },
    }
    ply_dir = os.path.join(work, "ply")
    os.makedirs(ply_dir, exist_ok=True)
    for k, prim in enumerate(gltf_scene.primitives(doc, buffers)):
        name = names[prim.material] if prim.material is not None else "default"
        path = os.path.join(ply_dir, "%s-%d.ply" % (prim.mesh_name, k))
        gltf_scene.write_ply(path, prim.positions, prim.normals, prim.triangles)
        b = mats[name]
        shape = {"type": "ply", "filename": path, "bsdf": mitsuba_bsdf(b),
                 # A primitive without normals gets flat normals in the baker.
                 "face_normals": prim.normals is None}
        if max(b["emission"]) > 0:
            # One-sided, from the side the triangles face, like the baker's emitters.
            shape["emitter"] = {"type": "area", "radiance": {"type": "rgb",
                                                             "value": list(b["emission"])}}
        scene["shape-%d-%s" % (k, name)] = shape
    for k, light in enumerate(gltf_scene.point_lights(doc)):
        scene["point-%d" % k] = {"type": "point", "position": list(light["position"]),
                                 "intensity": {"type": "rgb", "value": light["intensity"]}}
    if env and "color" in env:
        scene["sky"] = {"type": "constant", "radiance": {"type": "rgb", "value": env["color"]}}
    if env and "map" in env:
        # Mitsuba reads a lat-long map turned half a turn about +Y from the project's
        # convention (its centre column looks along +Z, u = 0.25 along +X), so to_world turns
        # it back. Both interpolate bilinearly with column centres at (x + 0.5) / width, but
        # Mitsuba puts the first and last rows on the poles (row y at v = y / (height - 1))
        # where the project puts them half a texel away and clamps beyond them; the map is
        # handed over with its rows refined so that Mitsuba's interpolation is the project's
        # exactly (mitsuba_rows).
        # The config's `rotation` (degrees about +Y, right-hand rule, docs/config.md) is
        # Mitsuba's rotate about +Y by the same angle, applied after the half turn.
        turn = 180.0 + float(env.get("rotation", 0.0))
        scene["sky"] = {"type": "envmap", "filename": mitsuba_rows_file(env["map"]),
                        "to_world": mi.ScalarTransform4f().rotate([0, 1, 0], turn)}
    return mi.load_dict(scene), mats


def pixel_materials(scene, width, height):
    """The name of the material seen at each pixel centre ('background' where nothing is),
    from Mitsuba's own ray casting (the region masks for per-material means)."""
    sensor = scene.sensors()[0]
    labels = np.empty((height, width), dtype=object)
    for y in range(height):
        for x in range(width):
            ray, _ = sensor.sample_ray(0.0, 0.5, mi.Point2f((x + 0.5) / width,
                                                           (y + 0.5) / height),
                                       mi.Point2f(0.5, 0.5))
            si = scene.ray_intersect(ray)
            labels[y, x] = si.shape.id().split("-", 2)[2] if si.is_valid() else "background"
    return labels


# ------------------------------------------------------------------------------------------
# The project's side.

def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return '"%s"' % v
    if isinstance(v, (list, tuple)):
        return "[%s]" % ", ".join(toml_value(c) for c in v)
    return repr(v)


def run(cmd):
    """Runs a project binary; its output is shown only when it fails."""
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    if r.returncode != 0:
        sys.exit("FAIL: %s exited with %d:\n%s" % (" ".join(cmd), r.returncode, r.stdout))


def bake_and_relight(case, bins, gltf_path, env, work, seed, tag):
    cfg = os.path.join(work, "%s-seed%d.toml" % (tag, seed))
    lines = ["scene = %s" % toml_value(os.path.abspath(gltf_path)),
             "output = %s" % toml_value(os.path.abspath(cfg[:-5] + ".prtbake")),
             "width = %d" % case["width"], "height = %d" % case["height"],
             "spp = %d" % case["bake_spp"], "reflections = %d" % case["reflections"],
             "seed = %d" % seed]
    if env and "color" in env:
        lines += ["", "[environment]", "color = %s" % toml_value(env["color"])]
    if env and "map" in env:
        lines += ["", "[environment]", "map = %s" % toml_value(os.path.abspath(env["map"]))]
        if env.get("rotation"):
            lines += ["rotation = %r" % float(env["rotation"])]
    for name, table in case["materials"].items():
        lines += ["", "[materials.%s]" % name]
        lines += ["%s = %s" % (k, toml_value(v)) for k, v in table.items()]
    with open(cfg, "w") as f:
        f.write("\n".join(lines) + "\n")
    run([os.path.join(bins, "bake"), cfg, "--quiet"])
    exr = cfg[:-5] + "-relit.exr"
    cmd = [os.path.join(bins, "relight"), cfg[:-5] + ".prtbake", "--out", exr]
    for key, value in case["edits"].items():
        text = ",".join(map(str, value)) if isinstance(value, list) else str(value)
        cmd += ["--set", "%s=%s" % (key, text)]
    run(cmd)
    return read_exr(exr)


def read_exr(path):
    return np.array(mi.Bitmap(path), dtype=np.float64)[..., :3]


# ------------------------------------------------------------------------------------------
# The comparison.

def luminance(rgb):
    return rgb @ np.array([0.2126, 0.7152, 0.0722])


def mean_and_variance(images):
    """The per-pixel mean of K independent images and the unbiased estimate of its variance
    (the sample variance over the K, divided by K)."""
    stack = np.stack(images)
    k = len(images)
    return stack.mean(axis=0), stack.var(axis=0, ddof=1) / k


def compare(project, mitsuba, labels):
    """Rows of (region, pixels, mean project, mean Mitsuba, difference %, worst z, bound
    used, ok) and the rel. L2 figures. Means are tested per channel; the table shows
    luminance means and the worst channel's z = |difference| / standard error."""
    p, var_p = mean_and_variance(project)
    m, var_m = mean_and_variance(mitsuba)
    var = var_p + var_m
    h, w = labels.shape
    regions = [("image", np.ones((h, w), bool))]
    for name in sorted(set(labels.ravel())):
        regions.append(("material " + name, labels == name))
    for ty in range(4):
        for tx in range(4):
            mask = np.zeros((h, w), bool)
            mask[ty * h // 4:(ty + 1) * h // 4, tx * w // 4:(tx + 1) * w // 4] = True
            regions.append(("tile %d,%d" % (ty, tx), mask))
    rows = []
    for name, mask in regions:
        n = int(mask.sum())
        mp, mm = p[mask].mean(axis=0), m[mask].mean(axis=0)
        se = np.sqrt(var[mask].sum(axis=0)) / n
        diff = np.abs(mp - mm)
        bound = Z * se + SLACK * np.abs(mm)
        tested = n >= MIN_PIXELS
        # A channel that is black on both sides with no noise passes (0 <= 0).
        ok = (not tested) or bool(np.all(diff <= bound))
        z = float(np.max(diff / np.maximum(se, 1e-30))) if tested else float("nan")
        lp, lm = float(luminance(mp)), float(luminance(mm))
        rows.append((name, n, lp, lm, 100 * (lp - lm) / max(abs(lm), 1e-30), z,
                     float(np.max(diff / np.maximum(bound, 1e-30))), tested, ok))
    err2 = float(((p - m) ** 2).sum())
    noise2 = float(var.sum())
    norm2 = float((m ** 2).sum())
    q, n_eff = noise_ratio_quantile(var_p, var_m, len(project), len(mitsuba))
    bound = math.sqrt((q * noise2 + (SLACK ** 2) * norm2) / norm2)
    rel_l2 = math.sqrt(err2 / norm2)
    l2 = dict(rel_l2=rel_l2, noise_rel_l2=math.sqrt(noise2 / norm2), ratio=err2 / noise2,
              q=q, n_eff=n_eff, bound=bound, ok=rel_l2 <= bound)
    return rows, l2


def noise_ratio_quantile(var_p, var_m, k_p, k_m):
    """The (1 - L2_ALPHA) point of err2 / noise2 when the two sides differ by noise alone.

    err2 (the squared difference, summed) and noise2 (the estimated variances, summed) are
    then sums of scaled chi-square terms, which Satterthwaite's rule treats as chi-square with
    n = (sum v)^2 / sum v^2 degrees of freedom, so the ratio is F-distributed. The figures
    matter: where a few pixels carry most of the noise (the edge of a light seen directly) n
    is small and the ratio spreads widely; where the noise is spread over the image it stays
    close to 1. Each pixel's channels count as one term (they are strongly correlated), which
    errs towards a wider bound. Returns the quantile and n of the numerator."""
    vp, vm = var_p.sum(axis=-1).ravel(), var_m.sum(axis=-1).ravel()
    v = vp + vm
    # A sample variance over k images has E[s^4] = sigma^4 (1 + 2 / (k - 1)): squaring the
    # estimates overstates sum v^2 by that factor.
    cp, cm = 1 + 2 / (k_p - 1), 1 + 2 / (k_m - 1)
    sum_v2 = float((vp ** 2).sum() / cp + (vm ** 2).sum() / cm + 2 * (vp * vm).sum())
    n_num = float(v.sum()) ** 2 / sum_v2
    # noise2 sums sample variances over k images: each is sigma^2 chi2(k - 1) / (k - 1).
    n_den = float(v.sum()) ** 2 / float((vp ** 2).sum() / cp / (k_p - 1)
                                       + (vm ** 2).sum() / cm / (k_m - 1))
    rng = np.random.default_rng(0)  # a fixed draw: the bound is the same on every run
    f = (rng.chisquare(n_num, 1_000_000) / n_num) / (rng.chisquare(n_den, 1_000_000) / n_den)
    return float(np.quantile(f, 1 - L2_ALPHA)), n_num


def print_table(title, rows, l2):
    print("\n%s" % title)
    print("  %-20s %6s %11s %11s %8s %7s %9s  %s" % ("region", "pixels", "project", "mitsuba",
                                                   "diff %", "max z", "/bound", "result"))
    for name, n, lp, lm, dpc, z, frac, tested, ok in rows:
        res = ("PASS" if ok else "FAIL") if tested else "(small)"
        print("  %-20s %6d %11.5f %11.5f %+8.2f %7.2f %9.2f  %s" % (name, n, lp, lm, dpc, z,
                                                                     frac, res))
    print("  rel. L2 %.4f, bound %.4f  %s" % (l2["rel_l2"], l2["bound"],
                                            "PASS" if l2["ok"] else "FAIL"))
    print("  (noise alone predicts %.4f, squared ratio %.2f; bound^2 = q noise^2 + (%.0f %%)^2 "
          "with q = %.2f, which pure noise exceeds with p = %g at %.0f effective pixels)"
          % (l2["noise_rel_l2"], l2["ratio"], 100 * SLACK, l2["q"], L2_ALPHA, l2["n_eff"]))
    print("  (means: luminance; max z = worst channel |diff| / standard error; /bound = worst "
          "channel |diff| / (%.1f SE + %.0f %% of the mean))" % (Z, 100 * SLACK))


PLANTS = ["black", "bright2x", "bias5", "mirror", "envrot90"]


def plant_image(img, plant):
    """A project image with a planted bug ('envrot90' is planted in the bake input)."""
    if plant == "black":
        return img * 0
    if plant == "bright2x":
        return img * 2
    if plant == "bias5":
        return img * 1.05
    if plant == "mirror":
        return img[:, ::-1]
    return img


def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release"),
                    help="folder holding the bake and relight binaries")
    ap.add_argument("--work", default=os.path.join(ROOT, "target", "mitsuba-work"),
                    help="scratch folder (emptied first)")
    ap.add_argument("--scenes", default=",".join(CASES), help="comma-separated subset")
    ap.add_argument("--first-seed", type=int, default=1,
                    help="seeds are this and the next replicas - 1 (for measuring the spread "
                         "of the figures under other seeds)")
    ap.add_argument("--plant", choices=["none", "all"] + PLANTS, default="none",
                    help="corrupt the project's side; with 'all', succeed only if every "
                         "planted bug fails the comparison")
    args = ap.parse_args()

    t_start = time.time()
    # The work folder is emptied first, so refuse one this script did not make.
    marker = os.path.join(args.work, ".mitsuba-work")
    if os.path.isdir(args.work) and os.listdir(args.work) and not os.path.exists(marker):
        sys.exit("--work %s: not empty and not made by compare.py; not touching it" % args.work)
    shutil.rmtree(args.work, ignore_errors=True)
    os.makedirs(args.work)
    open(marker, "w").close()
    worst = check_bsdf_mapping()
    print("BSDF mapping (docs/brdf.md vs Mitsuba eval, 300 direction pairs): max rel. "
          "difference %.2e" % worst)
    if worst > 1e-4:
        sys.exit("FAIL: Mitsuba's BSDF does not match docs/brdf.md's formula")

    plants = PLANTS if args.plant == "all" else ([] if args.plant == "none" else [args.plant])
    failures = []       # honest comparisons that failed
    caught = {p: [] for p in plants}
    for tag in args.scenes.split(","):
        case = CASES[tag]
        work = os.path.join(args.work, tag)
        os.makedirs(work)
        t0 = time.time()
        gltf_path, env = os.path.join(ROOT, case["scene"]), case["environment"]
        if case.get("generate"):
            gltf_path = os.path.join(args.work, case["scene"])
            env = dict(env, map=os.path.join(args.work, env["map"]))
            write_envsphere(os.path.dirname(gltf_path), env["map"])
        seeds = range(args.first_seed, args.first_seed + case["replicas"])
        project = [bake_and_relight(case, args.bin, gltf_path, env, work, s, tag)
                   for s in seeds]
        t_bake = time.time() - t0
        t0 = time.time()
        scene, _ = mitsuba_scene(case, gltf_path, env, work)
        mitsuba = [np.array(mi.render(scene, spp=case["mitsuba_spp"], seed=s), np.float64)
                   for s in seeds]
        labels = pixel_materials(scene, case["width"], case["height"])
        t_mts = time.time() - t0
        for s, img in zip(seeds, mitsuba):
            mi.Bitmap(img.astype(np.float32)).write(os.path.join(work, "mitsuba-seed%d.exr" % s))

        title = "%s: %dx%d, %d reflections; project: %d bakes x %d spp (%.1f s); Mitsuba: " \
                "%d renders x %d spp (%.1f s)" % (
                    tag, case["width"], case["height"], case["reflections"], len(seeds),
                    case["bake_spp"], t_bake, len(seeds), case["mitsuba_spp"], t_mts)
        if not plants:
            rows, l2 = compare(project, mitsuba, labels)
            print_table(title, rows, l2)
            if not (l2["ok"] and all(r[-1] for r in rows)):
                failures.append(tag)
            continue
        for plant in plants:
            if plant == "envrot90":
                if not (env and "map" in env):
                    continue
                # Bake again with the sky turned a quarter about +Y.
                pwork = os.path.join(work, "envrot90")
                os.makedirs(pwork)
                pgltf = os.path.join(pwork, os.path.basename(gltf_path))
                penv = dict(env, map=os.path.join(pwork, os.path.basename(env["map"])))
                write_envsphere(pwork, penv["map"], turn_quarter=True)
                planted = [bake_and_relight(case, args.bin, pgltf, penv, pwork, s, tag)
                           for s in seeds]
            else:
                planted = [plant_image(img, plant) for img in project]
            rows, l2 = compare(planted, mitsuba, labels)
            print_table("%s, PLANTED %s" % (title, plant), rows, l2)
            failed = [r[0] for r in rows if not r[-1]] + ([] if l2["ok"] else ["rel. L2"])
            caught[plant].append((tag, failed))

    print("\ntotal %.1f s" % (time.time() - t_start))
    if plants:
        # A planted bug is caught when the run fails, i.e. some scene fails. (A mirrored
        # furnace is the furnace: that scene is left-right symmetric.)
        print("\nplanted bug   scene       failing checks")
        missed = []
        for plant in plants:
            for tag, failed in caught[plant]:
                print("  %-11s %-11s %s" % (plant, tag, ("%d: %s" % (
                    len(failed), ", ".join(failed[:4]) + (", ..." if len(failed) > 4 else ""))
                    if failed else "none")))
            if not caught[plant]:
                print("  %-11s (no scene of this run has a sky map)" % plant)
            elif not any(failed for _, failed in caught[plant]):
                missed.append(plant)
        if missed:
            print("FAIL: not caught: %s" % ", ".join(missed))
            sys.exit(1)
        print("PASS: every planted bug fails the comparison")
        sys.exit(0)
    if failures:
        print("FAIL: the project's relit images and Mitsuba disagree in: %s" % ", ".join(failures))
        sys.exit(1)
    print("PASS: the project's relit images agree with Mitsuba 3 within the measured noise")


if __name__ == "__main__":
    main()
