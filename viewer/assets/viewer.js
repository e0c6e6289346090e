// The viewer's page (docs/viewer.md): controls built from the bake's metadata, requests over
// one WebSocket, frames drawn as they come. Hand-written, no build step, no outside script.
"use strict";

const $ = (id) => document.getElementById(id);

// What the test harness and the readouts read: frames drawn, the request each answers, the
// end-to-end latencies (input event to pixels on the canvas), the first frame's time.
const viewer = {
  session: null,
  sentSeq: 0,
  info: null,
  settings: null,
  frames: 0,
  lastSeq: -1,
  lastFrame: null,
  latencies: [],
  firstFrameMs: null,
  errors: [],
  reference: null,
  send: null,
  // Called with each frame's description once it is on the canvas (the timing harness waits
  // on it inside the page, so no polling from outside competes with the page for a core).
  onFrame: null,
};
window.viewer = viewer;

let socket = null;
let seq = 0;
const sentAt = new Map();
// The binary messages announced by the last text messages, in order.
const expected = [];
let referenceImages = { reference: null, difference: null, width: 0, height: 0 };
let orbit = null;

function send(request) {
  seq += 1;
  request.seq = seq;
  viewer.sentSeq = seq;
  sentAt.set(seq, performance.now());
  socket.send(JSON.stringify(request));
  return seq;
}
viewer.send = send;

// sRGB <-> linear for the colour pickers (a picker shows display colours; kd and ks are
// linear albedos).
const toLinear = (c) => (c <= 0.04045 ? c / 12.92 : Math.pow((c + 0.055) / 1.055, 2.4));
const toSrgb = (l) => (l <= 0.0031308 ? 12.92 * l : 1.055 * Math.pow(l, 1 / 2.4) - 0.055);
function hexOfLinear(rgb) {
  return "#" + rgb.map((l) => {
    const v = Math.round(Math.min(1, Math.max(0, toSrgb(l))) * 255);
    return v.toString(16).padStart(2, "0");
  }).join("");
}
function linearOfHex(hex) {
  return [1, 3, 5].map((i) => toLinear(parseInt(hex.slice(i, i + 2), 16) / 255));
}
const fmt = (x) => (Math.abs(x) >= 100 ? x.toFixed(0) : Math.abs(x) >= 1 ? x.toFixed(2) : x.toPrecision(3));

// A slider over [min, max], logarithmic when the range spans more than two decades
// (shininess), so every part of it can be reached.
function paramSlider(p, onValue) {
  // Blinn-Phong's shininess runs from 0: its logarithmic slider starts at 1.
  const lo = p.min > 0 || p.max <= 100 ? p.min : 1;
  const log = lo > 0 && p.max / lo > 100;
  p = { ...p, min: log ? lo : p.min };
  const input = document.createElement("input");
  input.type = "range";
  input.min = 0;
  input.max = 1000;
  const toValue = (pos) => (log ? p.min * Math.pow(p.max / p.min, pos / 1000) : p.min + (p.max - p.min) * pos / 1000);
  const toPos = (v) => (log ? 1000 * Math.log(v / p.min) / Math.log(p.max / p.min) : 1000 * (v - p.min) / (p.max - p.min));
  input.value = toPos(p.value);
  input.addEventListener("input", () => onValue(toValue(Number(input.value))));
  return { input, set: (v) => { input.value = toPos(v); } };
}

const controls = {};

function buildMaterials(info, settings) {
  const box = $("materials");
  box.textContent = "";
  for (const m of info.materials) {
    const fs = document.createElement("fieldset");
    const legend = document.createElement("legend");
    legend.textContent = `${m.name} (${m.family}${m.editable ? "" : ", fixed"})`;
    fs.appendChild(legend);
    if (!m.editable) {
      fs.className = "fixed";
      fs.appendChild(document.createTextNode("baked fixed: not editable"));
      box.appendChild(fs);
      continue;
    }
    for (const p of m.params) {
      const label = document.createElement("label");
      label.append(p.param + " ");
      const out = document.createElement("output");
      const key = `${m.name}.${p.param}`;
      if (p.param === "kd" || p.param === "ks") {
        const input = document.createElement("input");
        input.type = "color";
        input.dataset.material = m.name;
        input.dataset.param = p.param;
        input.value = hexOfLinear(p.value);
        input.addEventListener("input", () => {
          const value = linearOfHex(input.value);
          send({ type: "material", name: m.name, param: p.param, value });
          out.textContent = value.map(fmt).join(", ");
        });
        label.appendChild(input);
        controls[key] = { set: (v) => { input.value = hexOfLinear(v); out.textContent = v.map(fmt).join(", "); } };
      } else {
        const slider = paramSlider(p, (value) => {
          send({ type: "material", name: m.name, param: p.param, value });
          out.textContent = fmt(value);
        });
        slider.input.dataset.material = m.name;
        slider.input.dataset.param = p.param;
        if (p.sampled) {
          slider.input.title = `valid ${p.min} to ${p.max}; the bake sampled ${p.sampled[0]} to ${p.sampled[1]} (beyond it, rendered clamped)`;
        }
        label.appendChild(slider.input);
        controls[key] = { set: (v) => { slider.set(v); out.textContent = fmt(v); } };
      }
      label.appendChild(out);
      fs.appendChild(label);
    }
    box.appendChild(fs);
  }
  applySettings(settings);
}

// Puts every control at the settings the server holds (after a hello, or a refusal).
function applySettings(s) {
  viewer.settings = s;
  for (const [name, params] of Object.entries(s.materials)) {
    for (const [param, v] of Object.entries(params)) {
      const c = controls[`${name}.${param}`];
      if (c) c.set(v);
    }
  }
  $("exposure").value = Math.log2(Math.max(s.exposure, 1e-6)).toFixed(1);
  $("exposure-out").textContent = fmt(s.exposure);
  $("tone").value = s.tone;
  if (s.view) {
    $("environment").value = s.view.environment;
    $("rotation").value = s.view.rotation;
    $("rotation-out").textContent = fmt(s.view.rotation);
    $("intensity").value = Math.log2(Math.max(s.view.intensity, 1e-6));
    $("intensity-out").textContent = fmt(s.view.intensity);
    $("fov").value = s.view.camera.fov;
    $("fov-out").textContent = fmt(s.view.camera.fov);
    $("image-size").value = `${s.view.width}x${s.view.height}`;
    orbit = orbitOf(s.view.camera);
  }
}

// The camera as an orbit about its target: distance, yaw about +Y, pitch above the horizon.
function orbitOf(cam) {
  const d = [0, 1, 2].map((i) => cam.eye[i] - cam.target[i]);
  const dist = Math.hypot(d[0], d[1], d[2]);
  return {
    target: cam.target.slice(),
    dist,
    yaw: Math.atan2(d[0], d[2]),
    pitch: Math.asin(Math.max(-1, Math.min(1, d[1] / dist))),
    fov: cam.fov,
  };
}

function sendCamera() {
  const o = orbit;
  const eye = [
    o.target[0] + o.dist * Math.cos(o.pitch) * Math.sin(o.yaw),
    o.target[1] + o.dist * Math.sin(o.pitch),
    o.target[2] + o.dist * Math.cos(o.pitch) * Math.cos(o.yaw),
  ];
  send({ type: "camera", eye, target: o.target, fov: o.fov });
}

function buildView(info, settings) {
  $("view").hidden = false;
  for (const name of info.environments) {
    $("environment").add(new Option(name, name));
  }
  const sizes = ["256x256", "512x512", "768x768", "1024x1024", "640x480", "1280x720"];
  const current = `${settings.view.width}x${settings.view.height}`;
  if (!sizes.includes(current)) sizes.unshift(current);
  for (const s of sizes) $("image-size").add(new Option(s, s));
  $("environment").addEventListener("change", () => send({ type: "environment", name: $("environment").value }));
  $("rotation").addEventListener("input", () => {
    const value = Number($("rotation").value);
    $("rotation-out").textContent = fmt(value);
    send({ type: "rotation", value });
  });
  $("intensity").addEventListener("input", () => {
    const value = Math.pow(2, Number($("intensity").value));
    $("intensity-out").textContent = fmt(value);
    send({ type: "intensity", value });
  });
  $("fov").addEventListener("input", () => {
    orbit.fov = Number($("fov").value);
    $("fov-out").textContent = fmt(orbit.fov);
    sendCamera();
  });
  $("image-size").addEventListener("change", () => {
    const [width, height] = $("image-size").value.split("x").map(Number);
    send({ type: "size", width, height });
  });
  $("reset-camera").addEventListener("click", () => {
    orbit = orbitOf(viewer.initialCamera);
    $("fov").value = orbit.fov;
    sendCamera();
  });
  viewer.initialCamera = settings.view.camera;
  // Drag to orbit, shift-drag to pan, wheel to zoom.
  const canvas = $("relit");
  let drag = null;
  canvas.addEventListener("pointerdown", (e) => {
    drag = { x: e.clientX, y: e.clientY, pan: e.shiftKey };
    canvas.setPointerCapture(e.pointerId);
  });
  canvas.addEventListener("pointermove", (e) => {
    if (!drag) return;
    const dx = e.clientX - drag.x;
    const dy = e.clientY - drag.y;
    drag.x = e.clientX;
    drag.y = e.clientY;
    if (dx === 0 && dy === 0) return;
    if (drag.pan || e.shiftKey) {
      // Move the target in the image plane, by the distance a pixel covers at the target.
      const scale = 2 * orbit.dist * Math.tan((orbit.fov * Math.PI) / 360) / canvas.clientHeight;
      const right = [Math.cos(orbit.yaw), 0, -Math.sin(orbit.yaw)];
      const up = [
        -Math.sin(orbit.pitch) * Math.sin(orbit.yaw),
        Math.cos(orbit.pitch),
        -Math.sin(orbit.pitch) * Math.cos(orbit.yaw),
      ];
      for (let i = 0; i < 3; i++) orbit.target[i] += scale * (-dx * right[i] + dy * up[i]);
    } else {
      orbit.yaw -= dx * 0.01;
      orbit.pitch = Math.max(-1.5, Math.min(1.5, orbit.pitch + dy * 0.01));
    }
    sendCamera();
  });
  const end = () => { drag = null; };
  canvas.addEventListener("pointerup", end);
  canvas.addEventListener("pointercancel", end);
  canvas.addEventListener("wheel", (e) => {
    e.preventDefault();
    orbit.dist *= Math.exp(e.deltaY * 0.001);
    sendCamera();
  }, { passive: false });
}

function buildDisplay(info) {
  for (const t of info.tones) $("tone").add(new Option(t, t));
  $("exposure").addEventListener("input", () => {
    const value = Math.pow(2, Number($("exposure").value));
    $("exposure-out").textContent = fmt(value);
    send({ type: "exposure", value });
  });
  $("tone").addEventListener("change", () => send({ type: "tone", value: $("tone").value }));
  const toggle = $("reference-toggle");
  if (!info.reference.available) {
    toggle.disabled = true;
    $("reference-label").title = info.reference.reason;
    $("reference-label").classList.add("fixed");
  }
  toggle.addEventListener("change", () => {
    $("reference-figure").hidden = !toggle.checked;
    $("reference-status").textContent = toggle.checked ? "starting…" : "";
    send({ type: "reference", on: toggle.checked });
  });
  $("reference-show").addEventListener("change", drawReference);
  $("copy").addEventListener("click", async () => {
    $("command").select();
    try {
      await navigator.clipboard.writeText($("command").value);
    } catch (_) {
      document.execCommand("copy");
    }
  });
}

function fitCanvas(canvas, width, height) {
  if (canvas.width !== width || canvas.height !== height) {
    canvas.width = width;
    canvas.height = height;
    // A small bake is shown enlarged (pixelated), a large one at its size.
    const scale = Math.max(1, Math.floor(384 / Math.max(width, height)));
    canvas.style.width = `${width * scale}px`;
  }
}

function drawRgba(canvas, width, height, bytes) {
  fitCanvas(canvas, width, height);
  canvas.getContext("2d").putImageData(new ImageData(new Uint8ClampedArray(bytes), width, height), 0, 0);
}

function drawReference() {
  const r = referenceImages;
  const bytes = r[$("reference-show").value];
  if (bytes) drawRgba($("reference"), r.width, r.height, bytes);
}

async function drawFrame(meta, data) {
  const canvas = $("relit");
  if (meta.encoding === "png") {
    const bitmap = await createImageBitmap(new Blob([data], { type: "image/png" }),
      { colorSpaceConversion: "none", premultiplyAlpha: "none" });
    fitCanvas(canvas, meta.width, meta.height);
    canvas.getContext("2d").drawImage(bitmap, 0, 0);
  } else {
    drawRgba(canvas, meta.width, meta.height, data);
  }
  const now = performance.now();
  if (viewer.firstFrameMs === null) viewer.firstFrameMs = now;
  const t = sentAt.get(meta.seq);
  if (t !== undefined && meta.seq > 0) {
    viewer.latencies.push({
      seq: meta.seq, ms: now - t, arrived_ms: meta.arrivedAt - t, rendered: meta.rendered,
      render_ms: meta.render_ms, tonemap_ms: meta.tonemap_ms, encode_ms: meta.encode_ms,
    });
    $("latency-ms").textContent = (now - t).toFixed(1);
  }
  for (const k of sentAt.keys()) if (k <= meta.seq) sentAt.delete(k);
  viewer.frames += 1;
  viewer.lastSeq = meta.seq;
  viewer.lastFrame = meta;
  viewer.settings = meta.settings;
  $("frame-ms").textContent = (meta.render_ms + meta.tonemap_ms + meta.encode_ms).toFixed(1);
  $("size").textContent = `${meta.width}×${meta.height}`;
  $("command").value = meta.command;
  $("status").textContent = `frame ${viewer.frames}`;
  if (viewer.onFrame) viewer.onFrame(meta);
}

function onText(msg) {
  if (msg.type === "hello") {
    viewer.session = msg.session;
    viewer.info = msg.info;
    $("title").textContent = msg.info.bake;
    $("save-exr").href = `/api/session/${msg.session}/image.exr`;
    $("save-png").href = `/api/session/${msg.session}/image.png`;
    buildDisplay(msg.info);
    if (msg.info.kind === "vertex") buildView(msg.info, msg.settings);
    buildMaterials(msg.info, msg.settings);
    const encoding = new URLSearchParams(location.search).get("encoding");
    if (encoding) send({ type: "encoding", value: encoding });
  } else if (msg.type === "frame") {
    expected.push({ kind: "frame", meta: msg });
  } else if (msg.type === "reference") {
    expected.push({ kind: "reference", meta: msg }, { kind: "difference", meta: msg });
  } else if (msg.type === "reference_error") {
    $("reference-status").textContent = msg.message;
  } else if (msg.type === "error") {
    viewer.errors.push(msg);
    $("error").hidden = false;
    $("error").textContent = msg.message;
    setTimeout(() => { $("error").hidden = true; }, 6000);
    applySettings(msg.settings);
  }
}

function onBinary(data) {
  const what = expected.shift();
  if (!what) return;
  if (what.kind === "frame") {
    what.meta.arrivedAt = performance.now();
    drawFrame(what.meta, data);
  } else {
    const m = what.meta;
    referenceImages[what.kind] = data;
    referenceImages.width = m.width;
    referenceImages.height = m.height;
    if (what.kind === "difference") {
      viewer.reference = m;
      const l2 = m.rel_l2 === null ? "–" : m.rel_l2.toFixed(4);
      $("reference-status").textContent = `${m.spp} spp, relative L2 ${l2}${m.done ? " (done)" : ""}`;
      drawReference();
    }
  }
}

function connect() {
  const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`;
  socket = new WebSocket(url);
  socket.binaryType = "arraybuffer";
  socket.onmessage = (e) => {
    if (typeof e.data === "string") onText(JSON.parse(e.data));
    else onBinary(e.data);
  };
  socket.onclose = () => { $("status").textContent = "disconnected (reload to reconnect)"; };
}

connect();
