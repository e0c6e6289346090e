#!/usr/bin/env python3
"""Compares PRT bake with Mitsuba 3 (rendering) and Embree 4 (ray tracing) in one interleaved
run, and prints the ratios (docs/compare.md). Not part of the test suite: it measures, it does
not assert. Run it through bench/compare/run.sh, which provides the pinned packages.

(a) Rendering. One scene (scenes/cornell: area light, a GGX bunny and a Lambert tall box, both
    editable, 6 246 triangles), one material setting, the same size, samples per pixel and
    path depth for Mitsuba 3 (llvm_ad_rgb, `path` integrator, max_depth = reflections + 1), the
    project's `reference` (true BRDFs) and the project's `bake` + `relight` (baked with the
    config's materials, relit to the edited ones). Each image is compared with a high-spp
    Mitsuba ground truth (cached under target/compare/gt/): rel. L2 = |image - truth| / |truth|
    over all pixels and channels; efficiency = 1 / (rel. L2^2 x time), as a ratio to Mitsuba's.
(b) Rays. `bench compare-rays dump` writes each scene's triangles and the same incoherent
    bounce rays (cosine-distributed about the surface normal, leaving the points a camera sees)
    with our hits; Embree (embreex) traces those rays, each hit is checked against ours, and
    both are timed on closest-hit and occlusion queries, one thread and all threads.

Rounds alternate between the tools (ours, theirs, then theirs, ours, ...) so that other load on
the machine falls on both; times are medians over the rounds. Usage:

    bench/compare/run.sh                 # the full comparison (256x256, 256 spp; minutes)
    bench/compare/run.sh --quick         # smoke run of every step, under a minute
    bench/compare/run.sh --skip-render   # rays only (or --skip-rays)
"""

import argparse
import concurrent.futures
import hashlib
import importlib.util
import json
import os
import subprocess
import sys
import time

import numpy as np

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
# The Mitsuba mapping of the project's scenes lives with the correctness check in tests/mitsuba:
# its glTF reader, and its compare.py's material mapping (docs/brdf.md, "Matching Mitsuba 3")
# and scene export. compare.py is loaded under another name, as this file is compare.py too.
sys.path.insert(0, os.path.join(ROOT, "tests", "mitsuba"))
_spec = importlib.util.spec_from_file_location(
    "mitsuba_check", os.path.join(ROOT, "tests", "mitsuba", "compare.py"))
mitsuba_check = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(mitsuba_check)  # sets the scalar_rgb variant; ours is set in main()

import drjit as dr  # noqa: E402
import mitsuba as mi  # noqa: E402

VARIANT = "llvm_ad_rgb"

# The render scene: the Cornell box with the bunny baked as GGX (Mitsuba has no Blinn-Phong)
# and the tall box as an editable Lambert surface; relit to other colours and roughness.
CASE = dict(
    scene="scenes/cornell/cornell.gltf",
    materials={
        "bunny": dict(editable=True, family="ggx", kd=[0.55, 0.5, 0.45], ks=0.25, alpha=0.3),
        "tall_box": dict(editable=True, family="diffuse", kd=0.5),
    },
    edits={"bunny.kd": [0.7, 0.35, 0.25], "bunny.alpha": 0.4,
           "tall_box.kd": [0.35, 0.5, 0.65]},
)


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def median(values):
    return float(np.median(np.asarray(values, dtype=np.float64)))


def rel_l2(img, truth):
    return float(np.sqrt(((img - truth) ** 2).sum() / (truth ** 2).sum()))


def run_json(cmd):
    """Runs a project binary with --json; returns (its JSON, wall seconds)."""
    t0 = time.perf_counter()
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        sys.exit("FAIL: %s exited with %d:\n%s%s" % (" ".join(cmd), r.returncode, r.stdout,
                                                      r.stderr))
    return json.loads(r.stdout.strip().splitlines()[-1]), wall


# ------------------------------------------------------------------------------------------
# (a) Rendering

class Render:
    def __init__(self, args):
        self.args = args
        self.case = dict(CASE, width=args.width, height=args.height,
                         reflections=args.reflections, sampler=args.mitsuba_sampler)
        self.gltf = os.path.join(ROOT, CASE["scene"])
        self.work = os.path.join(args.work, "render")
        os.makedirs(self.work, exist_ok=True)
        t0 = time.perf_counter()
        # tests/mitsuba/compare.py: triangles as PLY, camera, the BRDF mapping, the area light.
        self.scene, _ = mitsuba_check.mitsuba_scene(self.case, self.gltf, None, self.work)
        self.load_s = time.perf_counter() - t0

    def mitsuba(self, spp, seed, scene=None):
        t0 = time.perf_counter()
        img = np.array(mi.render(scene or self.scene, spp=spp, seed=seed),
                       dtype=np.float64)[..., :3]
        return img, time.perf_counter() - t0

    def ground_truth(self):
        """Mitsuba at --gt-spp, the mean of renders of at most 2^24 samples each (seeds apart
        from the timed renders'), cached under <work>/gt by everything that determines it."""
        a, c = self.args, self.case
        with open(self.gltf, "rb") as f:
            scene_hash = hashlib.sha256(f.read()).hexdigest()
        chunk = max(1, min(a.gt_spp, (1 << 24) // (a.width * a.height)))
        chunk = 1 << (chunk.bit_length() - 1)  # a power of two: ldsampler's sample counts
        key = json.dumps(dict(scene=scene_hash, materials=c["materials"], edits=c["edits"],
                              width=a.width, height=a.height, reflections=a.reflections,
                              spp=a.gt_spp, chunk=chunk, variant=VARIANT,
                              sampler=a.gt_sampler,
                              mitsuba=mi.__version__, drjit=dr.__version__), sort_keys=True)
        digest = hashlib.sha256(key.encode()).hexdigest()[:16]
        folder = os.path.join(a.work, "gt")
        path = os.path.join(folder, "gt-%s.npy" % digest)
        if os.path.exists(path):
            log("ground truth: cached %s" % os.path.relpath(path, ROOT))
            return np.load(path), path, None
        os.makedirs(folder, exist_ok=True)
        passes = (a.gt_spp + chunk - 1) // chunk
        log("ground truth: %d spp in %d Mitsuba renders, sampler %s (cached afterwards)"
            % (a.gt_spp, passes, a.gt_sampler))
        gt_scene, _ = mitsuba_check.mitsuba_scene(dict(self.case, sampler=a.gt_sampler),
                                                  self.gltf, None, self.work)
        t0 = time.perf_counter()
        acc = np.zeros((a.height, a.width, 3))
        total = 0
        for k in range(passes):
            spp = min(chunk, a.gt_spp - total)
            img, _ = self.mitsuba(spp, 1_000_000 + k, gt_scene)
            acc += img * spp
            total += spp
        gt = acc / total
        seconds = time.perf_counter() - t0
        np.save(path, gt)
        mi.Bitmap(gt.astype(np.float32)).write(path[:-4] + ".exr")
        with open(path[:-4] + ".json", "w") as f:
            f.write(key + "\n")
        return gt, path, seconds

    def config(self, seed):
        a = self.args
        cfg = os.path.join(self.work, "bake-seed%d.toml" % seed)
        toml = mitsuba_check.toml_value
        lines = ["scene = %s" % toml(self.gltf), 'mode = "pixel"',
                 "output = %s" % toml(cfg[:-5] + ".prtbake"),
                 "width = %d" % a.width, "height = %d" % a.height, "spp = %d" % a.spp,
                 "reflections = %d" % a.reflections, "seed = %d" % seed]
        for name, table in CASE["materials"].items():
            lines += ["", "[materials.%s]" % name]
            lines += ["%s = %s" % (k, toml(v)) for k, v in table.items()]
        with open(cfg, "w") as f:
            f.write("\n".join(lines) + "\n")
        return cfg

    def edit_flags(self):
        out = []
        for key, value in CASE["edits"].items():
            text = ",".join(map(str, value)) if isinstance(value, list) else str(value)
            out += ["--set", "%s=%s" % (key, text)]
        return out

    def reference(self, seed, bin_dir):
        cfg = self.config(seed)
        exr = cfg[:-5] + "-reference.exr"
        j, wall = run_json([os.path.join(bin_dir, "reference"), cfg, "--json",
                            "--out", exr] + self.edit_flags())
        return mitsuba_check.read_exr(exr), j["seconds"], wall

    def bake(self, seed, bin_dir):
        cfg = self.config(seed)
        bake, bake_wall = run_json([os.path.join(bin_dir, "bake"), cfg, "--json"])
        exr = cfg[:-5] + "-relit.exr"
        relight, relight_wall = run_json([os.path.join(bin_dir, "relight"),
                                          cfg[:-5] + ".prtbake", "--out", exr, "--json"]
                                         + self.edit_flags())
        os.remove(cfg[:-5] + ".prtbake")  # tens of MB per round at 256x256
        seconds = bake["seconds"] + relight["seconds_per_frame_median"]
        return mitsuba_check.read_exr(exr), seconds, bake_wall + relight_wall, bake


def render_comparison(args, report):
    r = Render(args)

    def bin_of(tool):
        return args.bin_before if tool.endswith("-before") else args.bin

    gt, gt_path, gt_seconds = r.ground_truth()
    # Dr.Jit compiles the renderer's kernels on the first render of a process (and caches
    # them); a 1-spp render takes that cost out of the timed rounds.
    r.mitsuba(1, 0)
    tools = ["mitsuba", "reference", "bake"]
    if args.bin_before:
        # The binaries of an earlier commit, in the same interleaved rounds.
        tools += ["reference-before", "bake-before"]
    rows = {t: dict(seconds=[], wall=[], err=[]) for t in tools}
    bake_parts = []
    for rnd in range(args.rounds):
        seed = rnd + 1
        order = tools if rnd % 2 == 0 else tools[::-1]
        for tool in order:
            if tool == "mitsuba":
                img, s = r.mitsuba(args.spp, seed)
                wall = s
            elif tool.startswith("reference"):
                img, s, wall = r.reference(seed, bin_of(tool))
            else:
                img, s, wall, summary = r.bake(seed, bin_of(tool))
                if tool == "bake":
                    bake_parts.append(dict(basis_s=summary.get("basis_seconds"),
                                           trace_s=summary["timings"]["trace_seconds"],
                                           seconds=summary["seconds"]))
            e = rel_l2(img, gt)
            rows[tool]["seconds"].append(s)
            rows[tool]["wall"].append(wall)
            rows[tool]["err"].append(e)
            log("round %d/%d %-9s %7.2f s  rel. L2 %.3f %%" % (rnd + 1, args.rounds, tool, s,
                                                               100 * e))
    a = args
    print("\n(a) Rendering: scenes/cornell (6 246 triangles, area light; bunny GGX and tall box "
          "Lambert, both editable, relit), %dx%d, %d spp, %d reflections (Mitsuba max_depth %d)"
          % (a.width, a.height, a.spp, a.reflections, a.reflections + 1))
    print("    ground truth: Mitsuba %s, %d spp, sampler %s (%s%s)" % (
        VARIANT, a.gt_spp, a.gt_sampler, os.path.relpath(gt_path, ROOT),
        "" if gt_seconds is None else ", %.0f s" % gt_seconds))
    print("    %d interleaved rounds (time: median, error: RMS); Mitsuba %s (sampler %s), drjit "
          "%s, %d threads; ours %s%s; Mitsuba scene load %.2f s (not timed)" % (
              a.rounds, mi.__version__, a.mitsuba_sampler, dr.__version__, dr.thread_count(),
              a.bin, "" if not a.bin_before else ", before " + a.bin_before, r.load_s))
    names = {"mitsuba": "Mitsuba 3 path", "reference": "ours: reference",
             "bake": "ours: bake + relight", "reference-before": "before: reference",
             "bake-before": "before: bake + relight"}
    print("  %-22s %9s %9s %10s %15s %12s %11s" % ("renderer", "time s", "wall s", "rel. L2 %",
                                                   "(min-max) %", "efficiency", "vs Mitsuba"))
    # Time: the median over rounds (robust to other load on the machine). Error: the root mean
    # square over rounds (seeds), since efficiency needs the expected squared error.
    rms = {t: float(np.sqrt(np.mean(np.square(rows[t]["err"])))) for t in tools}
    eff = {t: 1.0 / (rms[t] ** 2 * median(rows[t]["seconds"])) for t in tools}
    for tool in tools:
        print("  %-22s %9.2f %9.2f %10.3f %7.3f-%-7.3f %12.4g %10.3fx" % (
            names[tool], median(rows[tool]["seconds"]), median(rows[tool]["wall"]),
            100 * rms[tool], 100 * min(rows[tool]["err"]), 100 * max(rows[tool]["err"]),
            eff[tool], eff[tool] / eff["mitsuba"]))
    if bake_parts:
        print("    bake time = bake's own `seconds` (basis %.2f s + trace %.2f s + rest) + "
              "relight frame; time ratio bake / Mitsuba %.2f, reference / Mitsuba %.2f" % (
                  median([p["basis_s"] or 0.0 for p in bake_parts]),
                  median([p["trace_s"] for p in bake_parts]),
                  median(rows["bake"]["seconds"]) / median(rows["mitsuba"]["seconds"]),
                  median(rows["reference"]["seconds"]) / median(rows["mitsuba"]["seconds"])))
    print("    (time: the tool's own figure, median over rounds, scene loading and BVH build "
          "excluded on both sides; wall: our process, or Mitsuba's render call; rel. L2: root "
          "mean square over the rounds' seeds; efficiency = 1 / (rel. L2^2 x time) in 1/s)")
    report["render"] = dict(width=a.width, height=a.height, spp=a.spp,
                            reflections=a.reflections, gt_spp=a.gt_spp, rounds=a.rounds,
                            case=CASE, rounds_raw=rows, bake_parts=bake_parts,
                            rel_l2_rms=rms, efficiency=eff,
                            ratio={t: eff[t] / eff["mitsuba"] for t in tools})


# ------------------------------------------------------------------------------------------
# (c) Edits: the error of a relit edit against a fresh render of the edited scene

# A GGX sphere filling the view under a real HDR map (Poly Haven's studio: one small, very
# bright lamp), baked at alpha 0.12 and relit to other roughnesses of the basis' range
# [0.02, 1]; the bunny is off screen, the floor fills the corners.
EDIT_CASE = dict(
    scene="scenes/vitrine/vitrine.gltf",
    environment="scenes/envmaps/studio.exr",
    # fov in degrees (the config's unit): 0.35 radians.
    camera=dict(position=[-0.17, 0.2, 0.45], target=[-0.17, 0.119, 0.0], fov=20.053523),
    material="sphere",
    baked=dict(editable=True, family="ggx", kd=[0.1, 0.1, 0.1], ks=0.6, alpha=0.12),
)


class Edits:
    def __init__(self, args):
        self.args = args
        self.work = os.path.join(args.work, "edits")
        os.makedirs(self.work, exist_ok=True)

    def config(self, seed, spp, tag):
        a, c = self.args, EDIT_CASE
        toml = mitsuba_check.toml_value
        cfg = os.path.join(self.work, "%s-seed%d.toml" % (tag, seed))
        lines = ["scene = %s" % toml(os.path.join(ROOT, c["scene"])), 'mode = "pixel"',
                 "output = %s" % toml(cfg[:-5] + ".prtbake"),
                 "width = %d" % a.edit_size, "height = %d" % a.edit_size, "spp = %d" % spp,
                 "reflections = %d" % a.reflections, "seed = %d" % seed, "", "[camera]"]
        lines += ["%s = %s" % (k, toml(v)) for k, v in c["camera"].items()]
        lines += ["", "[environment]", "map = %s" % toml(os.path.join(ROOT, c["environment"])),
                  "", "[materials.%s]" % c["material"]]
        lines += ["%s = %s" % (k, toml(v)) for k, v in c["baked"].items()]
        if tag == "bake" and a.edit_basis_count:
            lines += ["", "[basis]", "count = %d" % a.edit_basis_count]
        with open(cfg, "w") as f:
            f.write("\n".join(lines) + "\n")
        return cfg

    def truth(self, alpha):
        """Our reference at --edit-gt-spp (another seed), cached by everything that sets it,
        the reference binary included."""
        a = self.args
        binary = os.path.join(a.edit_truth_bin or a.bin, "reference")
        with open(binary, "rb") as f:
            bin_hash = hashlib.sha256(f.read()).hexdigest()[:16]
        key = json.dumps(dict(case=EDIT_CASE, alpha=alpha, size=a.edit_size,
                              spp=a.edit_gt_spp, reflections=a.reflections, bin=bin_hash),
                         sort_keys=True)
        path = os.path.join(self.work, "gt-%s.npy" % hashlib.sha256(key.encode()).hexdigest()[:16])
        if not os.path.exists(path):
            log("edits: ground truth at alpha %g, %d spp" % (alpha, a.edit_gt_spp))
            cfg = self.config(1_000_000, a.edit_gt_spp, "gt")
            exr = cfg[:-5] + ".exr"
            run_json([binary, cfg, "--json", "--out", exr,
                      "--set", "%s.alpha=%g" % (EDIT_CASE["material"], alpha)])
            np.save(path, mitsuba_check.read_exr(exr))
        return np.load(path)

    def fresh(self, seed, alpha, bin_dir):
        cfg = self.config(seed, self.args.spp, "fresh")
        exr = cfg[:-5] + "-%g.exr" % alpha
        run_json([os.path.join(bin_dir, "reference"), cfg, "--json", "--out", exr,
                  "--set", "%s.alpha=%g" % (EDIT_CASE["material"], alpha)])
        return mitsuba_check.read_exr(exr)

    def relit(self, seed, alphas, bin_dir):
        cfg = self.config(seed, self.args.edit_bake_spp or self.args.spp, "bake")
        run_json([os.path.join(bin_dir, "bake"), cfg, "--json"])
        out = {}
        for alpha in alphas:
            exr = cfg[:-5] + "-%g.exr" % alpha
            run_json([os.path.join(bin_dir, "relight"), cfg[:-5] + ".prtbake", "--out", exr,
                      "--json", "--set", "%s.alpha=%g" % (EDIT_CASE["material"], alpha)])
            out[alpha] = mitsuba_check.read_exr(exr)
        os.remove(cfg[:-5] + ".prtbake")
        return out


def edit_comparison(args, report):
    e = Edits(args)
    alphas = [float(x) for x in args.edit_alphas.split(",")]
    truths = {alpha: e.truth(alpha) for alpha in alphas}
    bins = {"ours": args.bin}
    if args.bin_before:
        bins["before"] = args.bin_before
    err = {(b, kind, alpha): [] for b in bins for kind in ("fresh", "relit") for alpha in alphas}
    for rnd in range(args.rounds):
        seed = rnd + 1
        for b, bin_dir in bins.items():
            relit = e.relit(seed, alphas, bin_dir)
            for alpha in alphas:
                err[(b, "relit", alpha)].append(rel_l2(relit[alpha], truths[alpha]))
                fresh = e.fresh(seed, alpha, bin_dir)
                err[(b, "fresh", alpha)].append(rel_l2(fresh, truths[alpha]))
        log("edits: round %d/%d done" % (rnd + 1, args.rounds))
    c = EDIT_CASE
    print("\n(c) Edits: %s (GGX, kd %s, ks %g) baked at alpha %g under %s, %dx%d, %d spp, %d "
          "reflections, N_b %s; relit to each alpha against `reference` rendered at that alpha "
          "(a fresh render, %d spp); truth: `reference` at %d spp; rel. L2 RMS over %d seeds" % (
              c["material"], c["baked"]["kd"], c["baked"]["ks"], c["baked"]["alpha"],
              c["environment"], args.edit_size, args.edit_size, args.edit_bake_spp or args.spp,
              args.reflections, args.edit_basis_count or "default", args.spp, args.edit_gt_spp,
              args.rounds))
    print("  %-8s %7s %12s %12s %16s" % ("binaries", "alpha", "fresh %", "relit %",
                                         "relit / fresh"))
    rms = {k: float(np.sqrt(np.mean(np.square(v)))) for k, v in err.items()}
    for b in bins:
        for alpha in alphas:
            f, r = rms[(b, "fresh", alpha)], rms[(b, "relit", alpha)]
            print("  %-8s %7g %12.3f %12.3f %15.2fx" % (b, alpha, 100 * f, 100 * r, r / f))
    report["edits"] = dict(case=EDIT_CASE, alphas=alphas, size=args.edit_size, spp=args.spp,
                           bake_spp=args.edit_bake_spp or args.spp,
                           basis_count=args.edit_basis_count,
                           gt_spp=args.edit_gt_spp, rounds=args.rounds,
                           rel_l2_rms={"%s %s %g" % k: v for k, v in rms.items()},
                           rounds_raw={"%s %s %g" % k: v for k, v in err.items()})


# ------------------------------------------------------------------------------------------
# (b) Rays

class Ours:
    """`bench compare-rays time --serve`: builds our BVH over a dump once, then times one
    round (closest and occlusion, 1 and all threads) per line we send it."""

    def __init__(self, bench, folder, name):
        self.p = subprocess.Popen([bench, "compare-rays", "time", "--dir", folder, "--scene",
                                   name, "--serve"], stdin=subprocess.PIPE,
                                  stdout=subprocess.PIPE, text=True)
        self.head = self._read()["ready"]

    def _read(self):
        line = self.p.stdout.readline()
        if not line:
            sys.exit("FAIL: bench compare-rays time stopped (exit %s)" % self.p.wait())
        return json.loads(line)

    def round(self):
        self.p.stdin.write("round\n")
        self.p.stdin.flush()
        return {(f["query"], f["threads"]): f for f in self._read()["round"]}

    def close(self):
        self.p.stdin.close()
        self.p.wait()


class Embree:
    def __init__(self, tris, robust):
        from embreex import mesh_construction, rtcore_scene
        t0 = time.perf_counter()
        self.scene = rtcore_scene.EmbreeScene(robust=robust)
        mesh_construction.TriangleMesh(self.scene, tris)
        # The BVH is built (rtcCommitScene) on the first query.
        self.scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))
        self.build_s = time.perf_counter() - t0

    def pass_(self, origins, dirs, query, threads, pool):
        """One timed pass: embreex's run() loops over the rays in C with the GIL released
        (rtcIntersect1 / rtcOccluded1 per ray), so `threads` Python threads on contiguous
        slices trace in parallel."""
        q = "INTERSECT" if query == "closest" else "OCCLUDED"
        t0 = time.perf_counter()
        if threads == 1:
            ids = self.scene.run(origins, dirs, query=q)
        else:
            cuts = np.linspace(0, len(origins), threads + 1).astype(int)
            parts = pool.map(lambda k: self.scene.run(origins[cuts[k]:cuts[k + 1]],
                                                      dirs[cuts[k]:cuts[k + 1]], query=q),
                             range(threads))
            ids = np.concatenate(list(parts))
        seconds = time.perf_counter() - t0
        if query == "closest":
            hit = ids >= 0
            checksum = dict(hits=int(hit.sum()), triangle_sum=int(ids[hit].astype(np.int64).sum()))
        else:
            checksum = dict(hits=int((ids == 0).sum()), triangle_sum=0)
        return dict(seconds=seconds, checksum=checksum)


def agreement(emb, origins, dirs, ours_t, ours_tri, ours_occ):
    """Ray-by-ray: the same triangle; the same hit within tolerance (same triangle, or both hit
    at distances within 1e-5 + 1e-4 t: a neighbouring triangle at a shared edge); occlusion
    answers equal."""
    out = emb.scene.run(origins, dirs, output=1)
    tri, t = out["primID"], out["tfar"]
    hit_e, hit_o = tri >= 0, ours_tri >= 0
    same = tri == ours_tri
    close = hit_e & hit_o & (np.abs(t - ours_t) <= 1e-5 + 1e-4 * np.where(hit_o, ours_t, 0))
    occ = emb.scene.run(origins, dirs, query="OCCLUDED") == 0
    return dict(same_triangle=float(same.mean()), within_tolerance=float((same | close).mean()),
                hit_miss_differ=int((hit_e != hit_o).sum()),
                occlusion_equal=float((occ == (ours_occ != 0)).mean()))


def ray_comparison(args, report):
    bench = os.path.join(args.bin, "bench")
    folder = os.path.join(args.work, "rays")
    cmd = [bench, "compare-rays", "dump", "--dir", folder, "--rays", str(args.rays)]
    for s in args.ray_scenes.split(","):
        cmd += ["--scene", s]
    log("dumping rays: %s" % " ".join(cmd))
    r = subprocess.run(cmd, stdout=subprocess.PIPE, text=True)
    if r.returncode != 0:
        sys.exit("FAIL: %s exited with %d" % (" ".join(cmd), r.returncode))
    manifests = json.loads(r.stdout)
    import embreex
    threads_all = os.cpu_count() or 1
    pool = concurrent.futures.ThreadPoolExecutor(max_workers=threads_all)
    print("\n(b) Rays: ours (bench compare-rays) vs Embree %s via embreex %s (robust=%s, "
          "default build quality); %d rounds interleaved, medians; rays: %s/<scene>-rays.f32"
          % (embree_version(), embreex.__version__, args.embree_robust, args.rounds,
             os.path.relpath(folder, ROOT)))
    print("  %-8s %9s %-16s %7s %13s %15s %12s" % ("scene", "triangles", "query", "threads",
                                                    "ours Mrays/s", "Embree Mrays/s",
                                                    "ours/Embree"))
    report["rays"] = []
    for m in manifests:
        name = m["name"]
        f = {k: os.path.join(folder, v) for k, v in m["files"].items()}
        tris = np.fromfile(f["triangles"], "<f4").reshape(-1, 3, 3)
        rays = np.fromfile(f["rays"], "<f4").reshape(-1, 6)
        origins, dirs = np.ascontiguousarray(rays[:, :3]), np.ascontiguousarray(rays[:, 3:])
        ours_t = np.fromfile(f["hit_t"], "<f4")
        ours_tri = np.fromfile(f["hit_triangle"], "<i4")
        ours_occ = np.fromfile(f["occluded"], "u1")
        emb = Embree(tris, args.embree_robust)
        agree = agreement(emb, origins, dirs, ours_t, ours_tri, ours_occ)
        tracers = {"ours": Ours(bench, folder, name)}
        if args.bin_before:
            tracers["before"] = Ours(os.path.join(args.bin_before, "bench"), folder, name)
        keys = [(q, t) for q in ("closest", "occlusion")
                for t in sorted({1, threads_all})]
        # Our streams (several rays in flight, the same answers) against Embree's one ray at
        # a time, the only query embreex has; a "before" binary without them shows none.
        ours_keys = keys + [(q + "-stream", t) for q, t in keys]
        times = {k: dict(ours=[], embree=[], before=[]) for k in ours_keys}
        checks = {}
        sides = list(tracers) + ["embree"]
        for rnd in range(args.rounds):
            for side in (sides if rnd % 2 == 0 else sides[::-1]):
                if side != "embree":
                    res = tracers[side].round()
                    for k in ours_keys:
                        if k in res:
                            times[k][side].append(res[k]["seconds"])
                            checks[(k, side)] = res[k]["checksum"]
                else:
                    for k in keys:
                        res = emb.pass_(origins, dirs, k[0], k[1], pool)
                        times[k]["embree"].append(res["seconds"])
                        checks[(k, "embree")] = res["checksum"]
        for t in tracers.values():
            t.close()
        n = len(rays)
        rows = []
        for k in ours_keys:
            base = (k[0].replace("-stream", ""), k[1])
            to, te = median(times[k]["ours"]), median(times[base]["embree"])
            before = ""
            if times[k]["before"]:
                tb = median(times[k]["before"])
                before = "   before: %.2f Mrays/s, %.2fx Embree" % (n / tb / 1e6, te / tb)
            print("  %-8s %9d %-16s %7d %13.2f %15.2f %11.2fx%s" % (
                name, m["triangles"], k[0], k[1], n / to / 1e6, n / te / 1e6, te / to, before))
            rows.append(dict(query=k[0], threads=k[1], ours_s=times[k]["ours"],
                             embree_s=times[base]["embree"], ratio=te / to,
                             before_s=times[k]["before"],
                             ours_checksum=checks[(k, "ours")],
                             embree_checksum=checks[(base, "embree")]))
        # Our timed passes must have found exactly the dumped hits (same code, same rays).
        dump_ok = all(checks[(k, "ours")] == m["closest"] if k[0].startswith("closest")
                      else checks[(k, "ours")]["hits"] == m["occluded"] for k in ours_keys)
        print("  %-8s %d rays: same triangle %.4f %%, same hit within tolerance %.4f %%, "
              "hit/miss differ on %d, occlusion equal %.4f %%; Embree BVH build %.2f s; "
              "timed hits = dump's: %s" % (
                  name, n, 100 * agree["same_triangle"], 100 * agree["within_tolerance"],
                  agree["hit_miss_differ"], 100 * agree["occlusion_equal"], emb.build_s,
                  "yes" if dump_ok else "NO"))
        report["rays"].append(dict(scene=name, triangles=m["triangles"], rays=n,
                                   agreement=agree, build_embree_s=emb.build_s, rows=rows))
    print("    (ours/Embree: our throughput over Embree's, > 1 = ours faster; 1 thread and "
          "%d threads on this machine; a -stream row is our stream query against Embree's "
          "one-ray query of the same kind)" % threads_all)


def embree_version():
    # embreex prints "Embree version: X" in repr(EmbreeDevice); keep just the number.
    from embreex import rtcore
    text = repr(rtcore.EmbreeDevice())
    return text.split(":")[-1].strip() or "4"


# ------------------------------------------------------------------------------------------

def main():
    ap = argparse.ArgumentParser(description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default=os.path.join(ROOT, "target", "release"),
                    help="folder of the bake, relight, reference and bench binaries")
    ap.add_argument("--bin-before", help="folder of the binaries of an earlier commit (bench; "
                    "for the render half also bake, relight, reference), timed in the same "
                    "interleaved rounds as ours, Mitsuba and Embree")
    ap.add_argument("--gt-sampler", default="ldsampler",
                    help="Mitsuba's sampler for the ground truth (default ldsampler: its error "
                         "falls faster than independent sampling's, which matters once the "
                         "compared renders stratify their samples too)")
    ap.add_argument("--mitsuba-sampler", default="independent",
                    help="Mitsuba's sampler plugin (independent, stratified, multijitter, "
                         "ldsampler, ...; some need a square or power-of-two spp)")
    ap.add_argument("--work", default=os.path.join(ROOT, "target", "compare"),
                    help="scratch folder: renders, the cached ground truth, ray dumps")
    ap.add_argument("--quick", action="store_true",
                    help="smoke run: 64x64, 16 spp, ground truth 1024 spp, 2 rounds, 200K "
                         "rays on cornell and 100k (each of these can still be set)")
    ap.add_argument("--width", type=int)
    ap.add_argument("--height", type=int)
    ap.add_argument("--size", type=int, help="width and height")
    ap.add_argument("--spp", type=int)
    ap.add_argument("--reflections", type=int, default=2)
    ap.add_argument("--gt-spp", type=int, help="ground truth samples per pixel (default 8192)")
    ap.add_argument("--rounds", type=int, help="interleaved rounds (default 5)")
    ap.add_argument("--rays", type=int, help="rays per scene (default 2000000)")
    ap.add_argument("--ray-scenes", help="comma-separated: cornell, 100k, 1m, or bake configs "
                    "(default cornell,100k,1m)")
    ap.add_argument("--embree-robust", action="store_true",
                    help="Embree's robust mode (embreex's default; slower). Off: Embree's "
                         "own default")
    ap.add_argument("--skip-render", action="store_true")
    ap.add_argument("--skip-rays", action="store_true")
    ap.add_argument("--skip-edits", action="store_true")
    ap.add_argument("--edit-size", type=int, help="image size of the edit comparison "
                    "(default 96)")
    ap.add_argument("--edit-gt-spp", type=int, help="samples per pixel of the edit "
                    "comparison's truth (default 4096)")
    ap.add_argument("--edit-truth-bin", help="folder of the `reference` that renders the edit "
                    "comparison's truth (default --bin; its truths are cached per binary)")
    ap.add_argument("--edit-basis-count", type=int, help="basis BRDFs of the baked sphere "
                    "(N_b; default: the baker's, 8 for GGX)")
    ap.add_argument("--edit-bake-spp", type=int, help="samples per pixel of the edit "
                    "comparison's bakes (default --spp); a high count leaves the relit error "
                    "of the basis alone (its bias)")
    ap.add_argument("--edit-alphas", default="0.03,0.06,0.12,0.25,0.5",
                    help="roughnesses the sphere is relit to (comma-separated)")
    ap.add_argument("--json", help="also write every figure (per round) to this file "
                    "(default <work>/last.json)")
    args = ap.parse_args()
    quick = dict(size=64, spp=16, gt_spp=1024, rounds=2, rays=200_000,
                 ray_scenes="cornell,100k", edit_size=32, edit_gt_spp=256)
    full = dict(size=256, spp=256, gt_spp=8192, rounds=5, rays=2_000_000,
                ray_scenes="cornell,100k,1m", edit_size=96, edit_gt_spp=4096)
    for key, value in (quick if args.quick else full).items():
        if getattr(args, key) is None:
            setattr(args, key, value)
    args.width = args.width or args.size
    args.height = args.height or args.size
    for key in ("width", "height", "spp", "gt_spp", "rounds", "rays", "reflections",
                "edit_size", "edit_gt_spp"):
        if getattr(args, key) < 1:
            sys.exit("--%s must be at least 1" % key.replace("_", "-"))
    args.work = os.path.abspath(args.work)
    os.makedirs(args.work, exist_ok=True)
    try:
        mi.set_variant(VARIANT)
    except Exception as e:  # noqa: BLE001 (any failure here means the same thing)
        sys.exit("Mitsuba's %s variant did not load (%s). It needs LLVM: install Debian's "
                 "libllvm19 and set DRJIT_LIBLLVM_PATH to its libLLVM-19.so (run.sh does "
                 "both)." % (VARIANT, e))
    t0 = time.perf_counter()
    report = dict(command=" ".join(sys.argv), machine=dict(cpus=os.cpu_count()))
    if not args.skip_render:
        render_comparison(args, report)
    if not args.skip_rays:
        ray_comparison(args, report)
    if not args.skip_edits:
        edit_comparison(args, report)
    path = args.json or os.path.join(args.work, "last.json")
    with open(path, "w") as f:
        json.dump(report, f, indent=1, default=str)
    print("\ntotal %.0f s; every figure per round: %s" % (time.perf_counter() - t0,
                                                        os.path.relpath(path, ROOT)))


if __name__ == "__main__":
    main()
