"""The viewer in a real browser (docs/viewer.md, "Tests"): headless Chromium loads the page of
`view` over a per-pixel and a per-vertex bake, moves sliders, picks colours, orbits the camera
with the mouse, waits for the new frame, and checks the canvas' pixels against the PNG that
the page's "copy command" (`relight ...`) writes: the same bytes, or within one 8-bit step.
A refused request must show its message and leave the server serving.

With --screenshots DIR it saves a screenshot of each; with --measure N it times, in the page
(input event to pixels on the canvas), N moves of a per-pixel material slider (raw and PNG
frames), N camera orbit steps and N moves of the map's rotation and intensity sliders of the
per-vertex bake, and the first frames, and prints them as JSON (docs/viewer.md, "Measured")."""

import argparse
import base64
import json
import os
import shlex
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from webdriver import Browser, read_png  # noqa: E402

CANVAS_PIXELS = """
const c = document.getElementById('relit');
const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
let s = '';
for (let i = 0; i < d.length; i += 0x8000) s += String.fromCharCode.apply(null, d.subarray(i, i + 0x8000));
return [c.width, c.height, btoa(s)];
"""


class View:
    """A running `view` server."""

    def __init__(self, binary, bake, extra):
        self.spawned = time.perf_counter()
        self.proc = subprocess.Popen(
            [binary, bake, "--port", "0", *extra],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )
        self.url = self.proc.stdout.readline().strip()
        if not self.url.startswith("http://127.0.0.1:"):
            err = self.proc.stderr.read()
            raise RuntimeError(f"view did not start: {self.url!r} {err}")

    def stop(self):
        self.proc.terminate()
        self.proc.wait(10)


def set_input(b, css, value, event="input"):
    """Sets a control's value as a user would and fires its event; the request's number."""
    return b.js(
        """const e = document.querySelector(arguments[0]);
        if (!e) throw new Error('no control ' + arguments[0]);
        e.value = arguments[1]; e.dispatchEvent(new Event(arguments[2]));
        return window.viewer.sentSeq;""",
        css, value, event,
    )


def wait_frame(b, seq, timeout=60):
    b.wait_for("return window.viewer.lastSeq >= arguments[0];", timeout, seq)
    return b.js("return window.viewer.lastFrame;")


def canvas(b):
    w, h, data = b.js(CANVAS_PIXELS)
    return w, h, base64.b64decode(data)


def compare_with_relight(b, relight, workdir, label):
    """Runs the page's command with `relight` and compares its PNG with the canvas."""
    command = b.js("return document.getElementById('command').value;")
    args = shlex.split(command)
    assert args[0] == "relight", command
    out = os.path.join(workdir, f"{label}.png")
    args[0] = relight
    i = args.index("--out")
    args[i + 1] = out
    subprocess.run(args, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    w, h, rgba = canvas(b)
    pw, ph, ch, rgb = read_png(out)
    assert (w, h) == (pw, ph), f"{label}: canvas {w}x{h}, relight {pw}x{ph}: {command}"
    worst, differ = 0, 0
    for p in range(w * h):
        for c in range(3):
            d = abs(rgba[4 * p + c] - rgb[ch * p + c])
            worst = max(worst, d)
            differ += d > 0
    assert worst <= 1, f"{label}: canvas and relight differ by up to {worst} steps ({differ} channels): {command}"
    lit = sum(1 for p in range(w * h) if max(rgb[ch * p:ch * p + 3]) > 8)
    assert lit > w * h // 20, f"{label}: the image is nearly black ({lit} lit pixels)"
    print(f"  {label}: canvas = relight's PNG ({w}x{h}, {differ} channels differ by 1, max {worst}); {command}")
    return rgba


def refused_request_keeps_serving(b, bad, good_css, good_value):
    n = b.js("return window.viewer.errors.length;")
    b.js("window.viewer.send(arguments[0]);", bad)
    b.wait_for("return window.viewer.errors.length > arguments[0];", 30, n)
    msg = b.js("return window.viewer.errors[window.viewer.errors.length - 1].message;")
    shown = b.js("return document.getElementById('error').textContent;")
    assert msg and msg == shown, (msg, shown)
    seq = set_input(b, good_css, good_value)
    wait_frame(b, seq)
    print(f"  refused {json.dumps(bad)} with: {msg}; the next request was served")


def open_page(b, view, query=""):
    b.get(view.url + query)
    b.wait_for("return window.viewer && window.viewer.frames >= 1;", 60)
    first = time.perf_counter() - view.spawned
    page_ms = b.js("return window.viewer.firstFrameMs;")
    return first, page_ms


def check_pixel(b, args, workdir):
    view = View(args.view, args.pixel, ["--config", args.pixel_config] if args.pixel_config else [])
    try:
        first, page_ms = open_page(b, view)
        print(f"pixel bake {args.pixel}: first frame {first * 1e3:.0f} ms after starting view ({page_ms:.0f} ms after the page began loading)")
        before = canvas(b)[2]
        info = b.js("return window.viewer.info;")
        glossy = next(m for m in info["materials"] if m["editable"] and len(m["params"]) > 2)
        name, lobe = glossy["name"], glossy["params"][2]["param"]
        seq = set_input(b, f'input[data-material="{name}"][data-param="{lobe}"]', 800)
        frame = wait_frame(b, seq)
        assert frame["settings"]["materials"][name][lobe] != glossy["params"][2]["value"], frame["settings"]
        seq = set_input(b, f'input[data-material="{name}"][data-param="kd"]', "#c02020")
        wait_frame(b, seq)
        after = compare_with_relight(b, args.relight, workdir, "pixel-edited")
        assert after != before, "the edits did not change the canvas"
        seq = set_input(b, "#exposure", 1.5)
        wait_frame(b, seq)
        set_input(b, "#tone", "reinhard", "change")
        wait_frame(b, b.js("return window.viewer.sentSeq;"))
        compare_with_relight(b, args.relight, workdir, "pixel-exposure-reinhard")
        refused_request_keeps_serving(
            b, {"type": "material", "name": name, "param": lobe, "value": -3},
            f'input[data-material="{name}"][data-param="{lobe}"]', 300)
        refused_request_keeps_serving(
            b, {"type": "camera", "eye": [0, 0, 1], "target": [0, 0, 0], "fov": 40},
            "#exposure", 0)
        if args.screenshots:
            if args.pixel_config:
                b.js("document.getElementById('reference-toggle').click();")
                b.wait_for("return window.viewer.reference && window.viewer.reference.spp >= 2;", 120)
                print(f"  reference toggle: {b.js('return window.viewer.reference;')}")
            b.js("document.getElementById('error').hidden = true;")
            path = os.path.join(args.screenshots, "viewer-pixel.png")
            b.screenshot(path)
            print(f"  screenshot {path}")
    finally:
        view.stop()


def check_vertex(b, args, workdir):
    extra = ["--envs", args.envs] if args.envs else []
    view = View(args.view, args.vertex, extra + (["--config", args.vertex_config] if args.vertex_config else []))
    try:
        first, page_ms = open_page(b, view)
        print(f"vertex bake {args.vertex}: first frame {first * 1e3:.0f} ms after starting view ({page_ms:.0f} ms after the page began loading)")
        set_input(b, "#image-size", "256x256", "change")
        wait_frame(b, b.js("return window.viewer.sentSeq;"))
        compare_with_relight(b, args.relight, workdir, "vertex-default")
        before = b.js("return window.viewer.settings.view.camera;")
        b.drag("#relit", [(20, 0), (20, 8), (20, 8)])
        frame = wait_frame(b, b.js("return window.viewer.sentSeq;"))
        after = frame["settings"]["view"]["camera"]
        assert after["eye"] != before["eye"] and after["target"] == before["target"], (before, after)
        b.drag("#relit", [(-15, 6)], shift=True)
        frame = wait_frame(b, b.js("return window.viewer.sentSeq;"))
        panned = frame["settings"]["view"]["camera"]
        assert panned["target"] != after["target"], (after, panned)
        compare_with_relight(b, args.relight, workdir, "vertex-orbited")
        envs = b.js("return window.viewer.info.environments;")
        if len(envs) > 1:
            set_input(b, "#environment", envs[-1], "change")
        seq = set_input(b, "#rotation", 120)
        wait_frame(b, seq)
        seq = set_input(b, "#intensity", 0.5)
        wait_frame(b, seq)
        set_input(b, "#tone", "aces", "change")
        wait_frame(b, b.js("return window.viewer.sentSeq;"))
        compare_with_relight(b, args.relight, workdir, "vertex-env-rotated-aces")
        refused_request_keeps_serving(b, {"type": "size", "width": 100000, "height": 3}, "#rotation", 30)
        if args.screenshots:
            if args.vertex_config:
                b.js("document.getElementById('reference-toggle').click();")
                b.wait_for("return window.viewer.reference && window.viewer.reference.spp >= 2;", 180)
                print(f"  reference toggle: {b.js('return window.viewer.reference;')}")
            b.js("document.getElementById('error').hidden = true;")
            path = os.path.join(args.screenshots, "viewer-vertex.png")
            b.screenshot(path)
            print(f"  screenshot {path}")
    finally:
        view.stop()


# Runs a measurement inside the page: `count` times, `step(i)` (a function body that sends
# one request and returns its number), then waits for the frame answering it through
# `viewer.onFrame`, with nothing outside the page polling in between (WebDriver polls run
# scripts on the page's thread and take a core from the server on a small machine).
RUN_STEPS = """
const [count, body] = arguments;
const step = new Function('i', body);
window.measureRun = { done: false, error: null };
(async () => {
  try {
    for (let i = 0; i < count; i++) {
      const seq = step(i);
      await new Promise((resolve) => {
        viewer.onFrame = (meta) => { if (meta.seq >= seq) { viewer.onFrame = null; resolve(); } };
      });
    }
  } catch (e) {
    window.measureRun.error = String(e);
  }
  window.measureRun.done = true;
})();
"""


def latencies(b, count, step_js):
    """Runs the function body `step_js` (argument `i`; sends one request, returns its number)
    `count` times in the page, each after the previous request's frame is drawn; the page's
    end-to-end latencies and the server's frame times."""
    first = b.js("return window.viewer.latencies.length;")
    b.js(RUN_STEPS, count, step_js)
    b.wait_for("return window.measureRun.done;", 120, interval=0.5)
    err = b.js("return window.measureRun.error;")
    assert err is None, err
    lats = b.js("return window.viewer.latencies.slice(arguments[0]);", first)
    assert len(lats) == count and all(l["rendered"] for l in lats), lats
    ms = [l["ms"] for l in lats]
    server = [l["render_ms"] + l["tonemap_ms"] + l["encode_ms"] for l in lats]
    stages = {k: [l[k] for l in lats] for k in ["render_ms", "tonemap_ms", "encode_ms"]}
    q = lambda xs, f: sorted(xs)[min(len(xs) - 1, int(f * len(xs)))]  # noqa: E731
    arrived = [l["arrived_ms"] for l in lats]
    out = {"median_ms": statistics.median(ms), "p90_ms": q(ms, 0.9), "min_ms": min(ms),
           "arrived_median_ms": statistics.median(arrived),
           "server_median_ms": statistics.median(server), "frames": count}
    out.update({f"server_{k.removesuffix('_ms')}_median_ms": statistics.median(v) for k, v in stages.items()})
    return out


def measure(b, args):
    out = {}
    if args.pixel:
        for encoding in ["raw", "png"]:
            view = View(args.view, args.pixel, [])
            try:
                first, page_ms = open_page(b, view, f"?encoding={encoding}")
                info = b.js("return window.viewer.info;")
                glossy = next(m for m in info["materials"] if m["editable"] and len(m["params"]) > 2)
                css = f'input[data-material="{glossy["name"]}"][data-param="{glossy["params"][2]["param"]}"]'
                step = f"""const e = document.querySelector({json.dumps(css)});
                    e.value = 200 + (i * 37) % 700; e.dispatchEvent(new Event('input'));
                    return window.viewer.sentSeq;"""
                r = latencies(b, args.measure, step)
                r.update(first_frame_ms=first * 1e3, size=info["size"])
                out[f"pixel_slider_{encoding}"] = r
            finally:
                view.stop()
    if args.vertex:
        view = View(args.view, args.vertex, [])
        try:
            first, page_ms = open_page(b, view)
            w, h = args.measure_size
            wait_frame(b, b.js("return window.viewer.send(arguments[0]);", {"type": "size", "width": w, "height": h}))
            cam = b.js("return window.viewer.settings.view.camera;")
            # The eye turned 3 degrees more each step about the vertical through the target.
            orbit_step = f"""const c = {json.dumps(cam)};
                const d = [0, 1, 2].map((k) => c.eye[k] - c.target[k]);
                const a = 3 * (i + 1) * Math.PI / 180;
                const eye = [c.target[0] + d[0] * Math.cos(a) + d[2] * Math.sin(a), c.eye[1],
                             c.target[2] - d[0] * Math.sin(a) + d[2] * Math.cos(a)];
                return window.viewer.send({{ type: "camera", eye, target: c.target, fov: c.fov }});"""

            r = latencies(b, args.measure, orbit_step)
            r.update(first_frame_ms=first * 1e3, size=b.js("return [window.viewer.lastFrame.width, window.viewer.lastFrame.height];"))
            out["vertex_view_change"] = r
            # Light changes: the map turned, its intensity slider moved (the light stage, then
            # the material and view stages).
            for control, value in [("rotation", "(i * 7) % 360 - 180"), ("intensity", "((i * 13) % 41 - 20) / 10")]:
                step = f"""const e = document.getElementById('{control}');
                    e.value = {value}; e.dispatchEvent(new Event('input'));
                    return window.viewer.sentSeq;"""
                out[f"vertex_{control}_slider"] = latencies(b, args.measure, step)
        finally:
            view.stop()
    print(json.dumps(out, indent=1))


def main():
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("--view", required=True, help="the view binary")
    p.add_argument("--relight", required=True, help="the relight binary")
    p.add_argument("--pixel", help="a per-pixel bake file")
    p.add_argument("--pixel-config", help="its config (enables the reference toggle)")
    p.add_argument("--vertex", help="a per-vertex bake file")
    p.add_argument("--vertex-config", help="its config")
    p.add_argument("--envs", help="environment folder for the per-vertex bake")
    p.add_argument("--screenshots", help="save screenshots in this folder")
    p.add_argument("--measure", type=int, default=0, help="time this many frames instead of checking")
    p.add_argument("--measure-size", type=lambda s: tuple(int(x) for x in s.split("x")), default=(512, 512),
                   help="the per-vertex image size measured, WxH (the per-pixel size is the bake's)")
    args = p.parse_args()
    b = Browser()
    try:
        if args.measure:
            measure(b, args)
            return
        with tempfile.TemporaryDirectory(prefix="prt-viewer-browser-") as workdir:
            if args.pixel:
                check_pixel(b, args, workdir)
            if args.vertex:
                check_vertex(b, args, workdir)
        print("viewer browser check: passed")
    finally:
        b.close()


if __name__ == "__main__":
    main()
