#!/usr/bin/env python3
"""Generates the example scenes in scenes/ (glTF 2.0 + .bin, or .glb, and a bake.toml each).

Python 3 standard library only. Run from anywhere:

    python3 scenes/generate.py                      # rewrite all scenes
    python3 scenes/generate.py cornell ring         # only some

The Cornell box and the gallery need the Stanford bunny. It is committed inside
scenes/cornell/cornell.gltf (+ cornell.bin), and by default the generator reads it back from
there, so regenerating never needs the network. To take it afresh from its source, the npm
package `bunny` (1.0.1, by Mikola Lysenko, a decimated Stanford bunny: 1839 vertices, 3674
triangles; see scenes/README.md for source and licence), fetch the package and point the
generator at its index.js:

    cd /tmp && npm pack bunny && tar xzf bunny-1.0.1.tgz      # -> /tmp/package/index.js
    python3 scenes/generate.py --bunny /tmp/package/index.js cornell gallery

The gallery's environment map is not written here: scenes/envmaps/fetch.py decodes it from the
npm package @pmndrs/assets (see scenes/envmaps/README.md).

Conventions (docs/conventions.md): right-handed, +Y up, metres; cameras and spot lights look
down their local -Z; triangles are counter-clockwise seen from their front side; colours are
linear RGB. Output is deterministic: the same inputs give byte-identical files.
"""

import argparse
import json
import math
import os
import struct
import sys

HERE = os.path.dirname(os.path.abspath(__file__))

# glTF enums.
FLOAT, USHORT, UINT = 5126, 5123, 5125
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963


# ------------------------------------------------------------------------------------------
# Small vector helpers (tuples of floats).

def add(a, b):
    return (a[0] + b[0], a[1] + b[1], a[2] + b[2])


def sub(a, b):
    return (a[0] - b[0], a[1] - b[1], a[2] - b[2])


def mul(a, s):
    return (a[0] * s, a[1] * s, a[2] * s)


def dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def cross(a, b):
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def normalize(a):
    n = math.sqrt(dot(a, a))
    return (a[0] / n, a[1] / n, a[2] / n) if n > 0 else (0.0, 0.0, 0.0)


def look_at_quaternion(eye, target, up=(0.0, 1.0, 0.0)):
    """Rotation (x, y, z, w) turning local -Z towards target and local +Y towards up."""
    f = normalize(sub(target, eye))
    r = normalize(cross(f, up))
    u = cross(r, f)
    b = mul(f, -1.0)  # local +Z
    # Rotation matrix with columns r, u, b -> quaternion (Shepperd's method).
    m00, m01, m02 = r[0], u[0], b[0]
    m10, m11, m12 = r[1], u[1], b[1]
    m20, m21, m22 = r[2], u[2], b[2]
    tr = m00 + m11 + m22
    if tr > 0:
        s = math.sqrt(tr + 1.0) * 2
        w, x, y, z = 0.25 * s, (m21 - m12) / s, (m02 - m20) / s, (m10 - m01) / s
    elif m00 > m11 and m00 > m22:
        s = math.sqrt(1.0 + m00 - m11 - m22) * 2
        w, x, y, z = (m21 - m12) / s, 0.25 * s, (m01 + m10) / s, (m02 + m20) / s
    elif m11 > m22:
        s = math.sqrt(1.0 + m11 - m00 - m22) * 2
        w, x, y, z = (m02 - m20) / s, (m01 + m10) / s, 0.25 * s, (m12 + m21) / s
    else:
        s = math.sqrt(1.0 + m22 - m00 - m11) * 2
        w, x, y, z = (m10 - m01) / s, (m02 + m20) / s, (m12 + m21) / s, 0.25 * s
    return [x, y, z, w]


def y_rotation_quaternion(degrees):
    h = math.radians(degrees) / 2
    return [0.0, math.sin(h), 0.0, math.cos(h)]


# ------------------------------------------------------------------------------------------
# Meshes: dicts with "positions" (list of 3-tuples), optional "normals", "uvs", "indices"
# (flat list, counter-clockwise triangles).

class MeshData:
    def __init__(self):
        self.positions = []
        self.normals = []
        self.uvs = []
        self.indices = []

    def vertex(self, p, n=None, uv=None):
        self.positions.append(tuple(p))
        if n is not None:
            self.normals.append(tuple(n))
        if uv is not None:
            self.uvs.append(tuple(uv))
        return len(self.positions) - 1

    def tri(self, a, b, c):
        self.indices += [a, b, c]


def grid_quad(mesh, origin, edge_u, edge_v, nu, nv, facing):
    """A planar quad origin + s edge_u + t edge_v as an nu x nv grid of triangles, wound
    counter-clockwise seen from the side `facing` points to."""
    if dot(cross(edge_u, edge_v), facing) < 0:
        edge_u, edge_v, nu, nv = edge_v, edge_u, nv, nu
    n = normalize(cross(edge_u, edge_v))
    base = len(mesh.positions)
    for j in range(nv + 1):
        for i in range(nu + 1):
            s, t = i / nu, j / nv
            p = add(origin, add(mul(edge_u, s), mul(edge_v, t)))
            mesh.vertex(p, n, (s, 1.0 - t))
    for j in range(nv):
        for i in range(nu):
            a = base + j * (nu + 1) + i
            b, c, d = a + 1, a + nu + 2, a + nu + 1
            mesh.tri(a, b, c)
            mesh.tri(a, c, d)


def smooth_normals(positions, indices):
    """Area-weighted vertex normals (the cross product's length is twice the area)."""
    acc = [(0.0, 0.0, 0.0)] * len(positions)
    for k in range(0, len(indices), 3):
        a, b, c = indices[k:k + 3]
        n = cross(sub(positions[b], positions[a]), sub(positions[c], positions[a]))
        acc[a] = add(acc[a], n)
        acc[b] = add(acc[b], n)
        acc[c] = add(acc[c], n)
    return [normalize(n) if dot(n, n) > 0 else (0.0, 1.0, 0.0) for n in acc]


def signed_volume(positions, indices):
    v = 0.0
    for k in range(0, len(indices), 3):
        a, b, c = (positions[i] for i in indices[k:k + 3])
        v += dot(a, cross(b, c)) / 6.0
    return v


def check_winding(name, md, indexed):
    """Asserts that every triangle winds counter-clockwise seen from where its vertex normals
    point (the loader's geometric normals then agree with the shading normals)."""
    if not md.normals:
        return
    idx = md.indices if indexed else list(range(len(md.positions)))
    for k in range(0, len(idx), 3):
        a, b, c = idx[k:k + 3]
        g = cross(sub(md.positions[b], md.positions[a]), sub(md.positions[c], md.positions[a]))
        nsum = add(add(md.normals[a], md.normals[b]), md.normals[c])
        if dot(g, nsum) <= 0:
            sys.exit("generate.py bug: mesh %s triangle %d winds against its normals" % (name, k // 3))


# ------------------------------------------------------------------------------------------
# glTF writer.

class Gltf:
    def __init__(self):
        self.bin = bytearray()
        self.json = {
            "asset": {"version": "2.0", "generator": "prt-bake scenes/generate.py"},
            "scene": 0,
            "scenes": [{"nodes": []}],
            "nodes": [],
            "meshes": [],
            "materials": [],
            "accessors": [],
            "bufferViews": [],
            "buffers": [],
        }
        self.extensions = set()

    def _view(self, data, target):
        while len(self.bin) % 4:
            self.bin.append(0)
        view = {"buffer": 0, "byteOffset": len(self.bin), "byteLength": len(data), "target": target}
        self.bin += data
        self.json["bufferViews"].append(view)
        return len(self.json["bufferViews"]) - 1

    def _accessor(self, view, ctype, count, kind, **extra):
        acc = {"bufferView": view, "componentType": ctype, "count": count, "type": kind}
        acc.update(extra)
        self.json["accessors"].append(acc)
        return len(self.json["accessors"]) - 1

    def vec_accessor(self, values, kind, with_bounds=False):
        n = len(values[0])
        flat = [c for v in values for c in v]
        data = struct.pack("<%df" % len(flat), *flat)
        extra = {}
        if with_bounds:
            # Bounds of the float32-rounded values, as the spec requires.
            r = [struct.unpack("<f", struct.pack("<f", c))[0] for c in flat]
            extra["min"] = [min(r[i::n]) for i in range(n)]
            extra["max"] = [max(r[i::n]) for i in range(n)]
        return self._accessor(self._view(data, ARRAY_BUFFER), FLOAT, len(values), kind, **extra)

    def index_accessor(self, indices, vertex_count):
        if vertex_count <= 65535:
            data, ctype = struct.pack("<%dH" % len(indices), *indices), USHORT
        else:
            data, ctype = struct.pack("<%dI" % len(indices), *indices), UINT
        return self._accessor(self._view(data, ELEMENT_ARRAY_BUFFER), ctype, len(indices), "SCALAR")

    def material(self, name, base, metallic=0.0, roughness=1.0, emission=None, strength=1.0):
        m = {
            "name": name,
            "pbrMetallicRoughness": {
                "baseColorFactor": [base[0], base[1], base[2], 1.0],
                "metallicFactor": metallic,
                "roughnessFactor": roughness,
            },
        }
        if emission is not None:
            m["emissiveFactor"] = list(emission)
            if strength != 1.0:
                m["extensions"] = {"KHR_materials_emissive_strength": {"emissiveStrength": strength}}
                self.extensions.add("KHR_materials_emissive_strength")
        self.json["materials"].append(m)
        return len(self.json["materials"]) - 1

    def mesh(self, name, primitives):
        """primitives: list of (MeshData, material index, indexed?)."""
        prims = []
        for md, mat, indexed in primitives:
            check_winding(name, md, indexed)
            attrs = {"POSITION": self.vec_accessor(md.positions, "VEC3", with_bounds=True)}
            if md.normals:
                attrs["NORMAL"] = self.vec_accessor(md.normals, "VEC3")
            if md.uvs:
                attrs["TEXCOORD_0"] = self.vec_accessor(md.uvs, "VEC2")
            prim = {"attributes": attrs, "material": mat, "mode": 4}
            if indexed:
                prim["indices"] = self.index_accessor(md.indices, len(md.positions))
            prims.append(prim)
        self.json["meshes"].append({"name": name, "primitives": prims})
        return len(self.json["meshes"]) - 1

    def node(self, name, **fields):
        node = {"name": name}
        node.update(fields)
        self.json["nodes"].append(node)
        idx = len(self.json["nodes"]) - 1
        self.json["scenes"][0]["nodes"].append(idx)
        return idx

    def camera(self, name, eye, target, yfov_degrees, aspect=1.0):
        cams = self.json.setdefault("cameras", [])
        cams.append({
            "name": name,
            "type": "perspective",
            "perspective": {"yfov": math.radians(yfov_degrees), "aspectRatio": aspect,
                            "znear": 0.01, "zfar": 100.0},
        })
        return self.node(name, camera=len(cams) - 1, translation=list(eye),
                         rotation=look_at_quaternion(eye, target))

    def point_light(self, name, position, color, intensity):
        ext = self.json.setdefault("extensions", {}).setdefault("KHR_lights_punctual", {"lights": []})
        ext["lights"].append({"name": name, "type": "point", "color": list(color), "intensity": intensity})
        self.extensions.add("KHR_lights_punctual")
        return self.node(name, translation=list(position),
                         extensions={"KHR_lights_punctual": {"light": len(ext["lights"]) - 1}})

    def _finish_json(self):
        while len(self.bin) % 4:
            self.bin.append(0)
        if self.extensions:
            self.json["extensionsUsed"] = sorted(self.extensions)
        if not self.json["materials"]:
            del self.json["materials"]

    def write_gltf(self, folder, stem):
        self._finish_json()
        self.json["buffers"] = [{"uri": stem + ".bin", "byteLength": len(self.bin)}]
        with open(os.path.join(folder, stem + ".bin"), "wb") as f:
            f.write(self.bin)
        with open(os.path.join(folder, stem + ".gltf"), "w") as f:
            json.dump(self.json, f, indent=1)
            f.write("\n")

    def write_glb(self, folder, stem):
        self._finish_json()
        self.json["buffers"] = [{"byteLength": len(self.bin)}]
        js = json.dumps(self.json, separators=(",", ":")).encode()
        js += b" " * ((4 - len(js) % 4) % 4)
        total = 12 + 8 + len(js) + 8 + len(self.bin)
        with open(os.path.join(folder, stem + ".glb"), "wb") as f:
            f.write(struct.pack("<4sII", b"glTF", 2, total))
            f.write(struct.pack("<I4s", len(js), b"JSON") + js)
            f.write(struct.pack("<I4s", len(self.bin), b"BIN\0") + bytes(self.bin))


def write_text(path, text):
    with open(path, "w") as f:
        f.write(text)


# ------------------------------------------------------------------------------------------
# The bunny.

def bunny_from_npm(index_js):
    """Reads positions and cells from the npm package's index.js
    (`exports.positions=[[x,y,z],...];exports.cells=[[a,b,c],...]`)."""
    text = open(index_js).read()
    pos_part = text.split("exports.positions=", 1)[1].split("exports.cells=", 1)
    positions = json.loads(pos_part[0].strip().rstrip(";").rstrip(","))
    cells = json.loads(pos_part[1].strip().rstrip(";"))
    return [tuple(map(float, p)) for p in positions], [int(i) for c in cells for i in c]


def bunny_from_committed(gltf_path):
    """Reads the bunny back from a previously generated cornell.gltf (mesh "bunny")."""
    doc = json.load(open(gltf_path))
    data = open(os.path.join(os.path.dirname(gltf_path), doc["buffers"][0]["uri"]), "rb").read()
    mesh = next(m for m in doc["meshes"] if m["name"] == "bunny")
    prim = mesh["primitives"][0]

    def read(acc_index):
        acc = doc["accessors"][acc_index]
        view = doc["bufferViews"][acc["bufferView"]]
        off = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
        ncomp = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}[acc["type"]]
        fmt = {FLOAT: "f", USHORT: "H", UINT: "I"}[acc["componentType"]]
        n = acc["count"] * ncomp
        vals = struct.unpack_from("<%d%s" % (n, fmt), data, off)
        return [tuple(vals[i:i + ncomp]) for i in range(0, n, ncomp)] if ncomp > 1 else list(vals)

    return read(prim["attributes"]["POSITION"]), read(prim["indices"])


# ------------------------------------------------------------------------------------------
# Scenes.

def load_bunny(bunny_js):
    """The bunny in its native units (about 9.65 tall, base at y = 0), wound counter-clockwise
    seen from outside, positions rounded to float32: from the npm package's index.js when
    given, else read back from the committed scenes/cornell/cornell.gltf."""
    if bunny_js:
        positions, indices = bunny_from_npm(bunny_js)
    else:
        committed = os.path.join(HERE, "cornell", "cornell.gltf")
        if not os.path.exists(committed):
            sys.exit("scenes/cornell/cornell.gltf is missing; pass --bunny path/to/bunny/index.js")
        positions, indices = bunny_from_committed(committed)
    # Outward-facing triangles (counter-clockwise from outside): its enclosed volume tells
    # which way it winds.
    if signed_volume(positions, indices) < 0:
        for k in range(0, len(indices), 3):
            indices[k + 1], indices[k + 2] = indices[k + 2], indices[k + 1]
    positions = [tuple(struct.unpack("<f", struct.pack("<f", c))[0] for c in p) for p in positions]
    return positions, indices


def cornell(bunny_js):
    folder = os.path.join(HERE, "cornell")
    os.makedirs(folder, exist_ok=True)
    positions, indices = load_bunny(bunny_js)

    g = Gltf()
    # The classic Cornell box (www.graphics.cornell.edu/online/box/data.html) in metres:
    # 0.555 wide (X), 0.5488 high (Y), 0.5592 deep (Z), open towards +Z where the camera is.
    W, H, D = 0.555, 0.5488, 0.5592
    x0, x1 = -W / 2, W / 2
    white = g.material("white", (0.73, 0.73, 0.73))
    red = g.material("red", (0.63, 0.065, 0.05))
    green = g.material("green", (0.14, 0.45, 0.091))
    # Emission (17, 12, 4) W/(m^2 sr) as in pbrt's Cornell box, written as a normalized
    # emissiveFactor times KHR_materials_emissive_strength.
    light = g.material("light", (0.78, 0.78, 0.78), emission=(1.0, 12.0 / 17.0, 4.0 / 17.0),
                       strength=17.0)
    bunny_mat = g.material("bunny", (0.8, 0.75, 0.7), metallic=0.0, roughness=0.35)
    box_mat = g.material("tall_box", (0.73, 0.73, 0.73))

    n = 16  # wall tessellation, so the per-vertex mode has vertices to store transfer at
    walls = MeshData()
    grid_quad(walls, (x0, 0, 0), (W, 0, 0), (0, 0, -D), n, n, (0, 1, 0))     # floor
    grid_quad(walls, (x0, H, 0), (W, 0, 0), (0, 0, -D), n, n, (0, -1, 0))    # ceiling
    grid_quad(walls, (x0, 0, -D), (W, 0, 0), (0, H, 0), n, n, (0, 0, 1))     # back wall
    left = MeshData()
    grid_quad(left, (x0, 0, 0), (0, H, 0), (0, 0, -D), n, n, (1, 0, 0))
    right = MeshData()
    grid_quad(right, (x1, 0, 0), (0, H, 0), (0, 0, -D), n, n, (-1, 0, 0))
    # Ceiling light 0.13 x 0.105 m, 0.5 mm below the ceiling, facing down.
    lw, ld, ly = 0.13, 0.105, H - 0.0005
    lamp = MeshData()
    grid_quad(lamp, (-lw / 2, ly, -D / 2 - ld / 2), (0, 0, ld), (lw, 0, 0), 1, 1, (0, -1, 0))
    g.node("room", mesh=g.mesh("room", [(walls, white, True), (left, red, True),
                                        (right, green, True)]))
    g.node("light", mesh=g.mesh("light", [(lamp, light, True)]))

    # The tall box (0.165 x 0.165 x 0.33 m, turned 17 degrees) at the back left: written
    # unindexed and without normals, so loading it exercises flat-normal generation.
    box = MeshData()
    s, h = 0.165 / 2, 0.33
    corners = [(-s, -s), (s, -s), (s, s), (-s, s)]
    for i in range(4):
        (ax, az), (bx, bz) = corners[i], corners[(i + 1) % 4]
        # A side quad, turned around if needed so it winds counter-clockwise from outside.
        p = [(ax, 0, az), (bx, 0, bz), (bx, h, bz), (ax, h, az)]
        nrm = cross(sub(p[1], p[0]), sub(p[2], p[0]))
        if dot(nrm, (ax + bx, 0, az + bz)) < 0:
            p = [p[1], p[0], p[3], p[2]]
        for t in ((0, 1, 2), (0, 2, 3)):
            for k in t:
                box.vertex(p[k])
    top = [(x, h, z) for x, z in corners]
    if cross(sub(top[1], top[0]), sub(top[2], top[0]))[1] < 0:
        top.reverse()
    for t in ((0, 1, 2), (0, 2, 3)):
        for k in t:
            box.vertex(top[k])
    g.node("tall_box", mesh=g.mesh("tall_box", [(box, box_mat, False)]),
           translation=[-0.09, 0.0, -0.351], rotation=y_rotation_quaternion(17.0))

    # The bunny in its native units (about 9.65 tall) scaled to 0.19 m by its node, standing
    # on the floor at the front right, where the classic short box stands.
    bunny = MeshData()
    bunny.positions = positions
    bunny.normals = smooth_normals(positions, indices)
    bunny.indices = indices
    g.node("bunny", mesh=g.mesh("bunny", [(bunny, bunny_mat, True)]),
           translation=[0.093, 0.0, -0.2], rotation=y_rotation_quaternion(-20.0),
           scale=[0.02, 0.02, 0.02])

    # The classic camera: 0.8 m in front of the opening, 35 mm lens on 25 mm film (39.3 deg).
    g.camera("camera", (0.0, H / 2, 0.8), (0.0, H / 2, -D), 39.3)
    g.write_gltf(folder, "cornell")
    write_text(os.path.join(folder, "bake.toml"), """\
# Cornell box with the Stanford bunny (scenes/generate.py). Docs: docs/config.md
scene = "cornell.gltf"
mode = "pixel"
width = 256
height = 256
spp = 64
reflections = 2
seed = 0

# The bunny is a glossy glTF dielectric (roughness 0.35 -> ggx); bake it as Blinn-Phong.
[materials.bunny]
editable = true
family = "blinn-phong"
kd = [0.55, 0.5, 0.45]
ks = 0.25
shininess = 60

# The tall box is fully rough in the glTF (-> diffuse), so an editable ggx must say ks/alpha.
[materials.tall_box]
editable = true
family = "ggx"
kd = 0.5
ks = 0.3
alpha = 0.15
""")


def ring():
    folder = os.path.join(HERE, "ring")
    os.makedirs(folder, exist_ok=True)
    g = Gltf()
    floor_mat = g.material("floor", (0.6, 0.6, 0.6))
    ring_mat = g.material("ring", (0.95, 0.78, 0.4), metallic=1.0, roughness=0.08)

    floor = MeshData()
    F = 0.6  # 1.2 m square, 48 x 48 grid (for the per-vertex mode)
    grid_quad(floor, (-F, 0, F), (2 * F, 0, 0), (0, 0, -2 * F), 48, 48, (0, 1, 0))

    # A napkin ring: outer radius 0.1 m, wall 4 mm, 0.06 m tall, open ends, axis +Y.
    ro, ri, h, seg, hs = 0.1, 0.096, 0.06, 256, 4
    rg = MeshData()

    def band(radius, outward):
        base = len(rg.positions)
        for j in range(hs + 1):
            for i in range(seg + 1):
                a = 2 * math.pi * i / seg
                d = (math.cos(a), 0.0, -math.sin(a))
                nrm = d if outward else mul(d, -1.0)
                rg.vertex((radius * d[0], h * j / hs, radius * d[2]), nrm, (i / seg, j / hs))
        for j in range(hs):
            for i in range(seg):
                a = base + j * (seg + 1) + i
                b, c, d2 = a + 1, a + seg + 2, a + seg + 1
                # Counter-clockwise from the side the normal points to.
                if outward:
                    rg.tri(a, b, c)
                    rg.tri(a, c, d2)
                else:
                    rg.tri(a, c, b)
                    rg.tri(a, d2, c)

    def cap(y, up):
        base = len(rg.positions)
        nrm = (0.0, 1.0 if up else -1.0, 0.0)
        for i in range(seg + 1):
            a = 2 * math.pi * i / seg
            d = (math.cos(a), 0.0, -math.sin(a))
            rg.vertex((ro * d[0], y, ro * d[2]), nrm, (i / seg, 0.0))
            rg.vertex((ri * d[0], y, ri * d[2]), nrm, (i / seg, 1.0))
        for i in range(seg):
            o0, i0, o1, i1 = base + 2 * i, base + 2 * i + 1, base + 2 * i + 2, base + 2 * i + 3
            if up:
                rg.tri(o0, o1, i1)
                rg.tri(o0, i1, i0)
            else:
                rg.tri(o0, i1, o1)
                rg.tri(o0, i0, i1)

    band(ro, True)
    band(ri, False)
    cap(h, True)
    cap(0.0, False)

    g.node("floor", mesh=g.mesh("floor", [(floor, floor_mat, True)]))
    g.node("ring", mesh=g.mesh("ring", [(rg, ring_mat, True)]))
    # A low point light to the side: light entering the ring reflects off its inner wall and
    # focuses into the cardioid caustic on the floor inside the ring (thesis, Ring scene).
    g.point_light("lamp", (-0.8, 0.2, 0.05), (1.0, 0.97, 0.9), 6.0)
    g.camera("camera", (0.0, 0.42, 0.32), (0.0, 0.0, -0.01), 40.0)
    g.write_gltf(folder, "ring")
    write_text(os.path.join(folder, "bake.toml"), """\
# A glossy napkin ring casting a caustic under a point light (scenes/generate.py).
scene = "ring.gltf"
mode = "pixel"
width = 256
height = 256
spp = 64
reflections = 2
seed = 0

# The glTF ring is a smooth metal (-> ggx); bake it as a sharp Blinn-Phong lobe. Ks comes from
# the glTF (its base colour, as it is fully metallic).
[materials.ring]
editable = true
family = "blinn-phong"
kd = 0.02
shininess = 200
""")


def icosphere(subdivisions):
    t = (1.0 + math.sqrt(5.0)) / 2.0
    verts = [normalize(v) for v in [
        (-1, t, 0), (1, t, 0), (-1, -t, 0), (1, -t, 0),
        (0, -1, t), (0, 1, t), (0, -1, -t), (0, 1, -t),
        (t, 0, -1), (t, 0, 1), (-t, 0, -1), (-t, 0, 1)]]
    faces = [(0, 11, 5), (0, 5, 1), (0, 1, 7), (0, 7, 10), (0, 10, 11),
             (1, 5, 9), (5, 11, 4), (11, 10, 2), (10, 7, 6), (7, 1, 8),
             (3, 9, 4), (3, 4, 2), (3, 2, 6), (3, 6, 8), (3, 8, 9),
             (4, 9, 5), (2, 4, 11), (6, 2, 10), (8, 6, 7), (9, 8, 1)]
    for _ in range(subdivisions):
        cache = {}

        def mid(a, b):
            key = (min(a, b), max(a, b))
            if key not in cache:
                verts.append(normalize(mul(add(verts[a], verts[b]), 0.5)))
                cache[key] = len(verts) - 1
            return cache[key]

        new = []
        for a, b, c in faces:
            ab, bc, ca = mid(a, b), mid(b, c), mid(c, a)
            new += [(a, ab, ca), (b, bc, ab), (c, ca, bc), (ab, bc, ca)]
        faces = new
    return verts, [i for f in faces for i in f]


def loop_subdivide(positions, indices):
    """One level of Loop subdivision (C. Loop, 1987) of a triangle mesh: every triangle becomes
    four, winding kept. Interior vertices of valence n move to (1 - n beta) v + beta (sum of
    neighbours), beta = (5/8 - (3/8 + cos(2 pi / n) / 4)^2) / n; interior edges get the point
    3/8 (a + b) + 1/8 (c + d). Boundary (and non-manifold) edges get midpoints, boundary
    vertices with two boundary edges the 1/8, 3/4, 1/8 curve rule, other boundary vertices
    stay. Deterministic: edges are numbered in the order the triangles meet them."""
    nv = len(positions)
    edge_index = {}   # (min, max) -> index into edges
    edges = []        # [a, b, [opposite vertices]]
    neighbours = [[] for _ in range(nv)]
    for k in range(0, len(indices), 3):
        tri = indices[k:k + 3]
        for e in range(3):
            a, b, c = tri[e], tri[(e + 1) % 3], tri[(e + 2) % 3]
            key = (min(a, b), max(a, b))
            if key not in edge_index:
                edge_index[key] = len(edges)
                edges.append([key[0], key[1], []])
                neighbours[key[0]].append(key[1])
                neighbours[key[1]].append(key[0])
            edges[edge_index[key]][2].append(c)
    boundary_nbrs = [[] for _ in range(nv)]
    for a, b, opp in edges:
        if len(opp) != 2:
            boundary_nbrs[a].append(b)
            boundary_nbrs[b].append(a)
    out = []
    for v in range(nv):
        p = positions[v]
        if boundary_nbrs[v]:
            if len(boundary_nbrs[v]) == 2:
                q = add(positions[boundary_nbrs[v][0]], positions[boundary_nbrs[v][1]])
                p = add(mul(p, 0.75), mul(q, 0.125))
        else:
            n = len(neighbours[v])
            beta = (0.625 - (0.375 + 0.25 * math.cos(2 * math.pi / n)) ** 2) / n
            s = (0.0, 0.0, 0.0)
            for w in neighbours[v]:
                s = add(s, positions[w])
            p = add(mul(p, 1.0 - n * beta), mul(s, beta))
        out.append(p)
    for a, b, opp in edges:
        ab = add(positions[a], positions[b])
        if len(opp) == 2:
            out.append(add(mul(ab, 0.375), mul(add(positions[opp[0]], positions[opp[1]]), 0.125)))
        else:
            out.append(mul(ab, 0.5))
    new = []
    for k in range(0, len(indices), 3):
        a, b, c = indices[k:k + 3]
        ab = nv + edge_index[(min(a, b), max(a, b))]
        bc = nv + edge_index[(min(b, c), max(b, c))]
        ca = nv + edge_index[(min(c, a), max(c, a))]
        new += [a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca]
    return out, new


def torus_knot(p, q, radius, tube, segments, sides):
    """A (p, q) torus knot tube, closed (no duplicated seam vertices), with exact normals.
    The core curve, as three.js's TorusKnotGeometry draws it, for t in [0, 2 pi):
        C(t) = radius / 2 ((2 + cos q t) cos p t, (2 + cos q t) sin p t, sin q t)
    so it lies in the XY plane, facing +Z. The tube's circle at C(t) is spanned by N, the
    component of C(t) normal to the tangent (C never points along its tangent here), and
    B = T x N; a point C + tube (cos v N + sin v B) has the normal cos v N + sin v B, exact for a
    tube around a curve."""
    md = MeshData()
    for i in range(segments):
        t = 2 * math.pi * i / segments
        cq, sq, cp, sp = math.cos(q * t), math.sin(q * t), math.cos(p * t), math.sin(p * t)
        c = (radius / 2 * (2 + cq) * cp, radius / 2 * (2 + cq) * sp, radius / 2 * sq)
        # dC/dt.
        d = (radius / 2 * (-q * sq * cp - (2 + cq) * p * sp),
             radius / 2 * (-q * sq * sp + (2 + cq) * p * cp),
             radius / 2 * q * cq)
        tt = normalize(d)
        nn = normalize(sub(c, mul(tt, dot(c, tt))))
        bb = cross(tt, nn)
        for j in range(sides):
            v = 2 * math.pi * j / sides
            nrm = add(mul(nn, math.cos(v)), mul(bb, math.sin(v)))
            md.vertex(add(c, mul(nrm, tube)), nrm)
    for i in range(segments):
        for j in range(sides):
            a = i * sides + j
            b = ((i + 1) % segments) * sides + j
            c2 = ((i + 1) % segments) * sides + (j + 1) % sides
            d2 = i * sides + (j + 1) % sides
            md.tri(a, b, c2)
            md.tri(a, c2, d2)
    # Turn the winding round if it runs clockwise seen from the normals' side.
    a, b, c2 = md.indices[0:3]
    g = cross(sub(md.positions[b], md.positions[a]), sub(md.positions[c2], md.positions[a]))
    if dot(g, md.normals[a]) < 0:
        for k in range(0, len(md.indices), 3):
            md.indices[k + 1], md.indices[k + 2] = md.indices[k + 2], md.indices[k + 1]
    return md


def furnace():
    folder = os.path.join(HERE, "furnace")
    os.makedirs(folder, exist_ok=True)
    g = Gltf()
    mat = g.material("sphere", (0.5, 0.5, 0.5))
    verts, indices = icosphere(5)
    r = 0.5
    sphere = MeshData()
    for v in verts:
        # Exact normals: the unit position. UVs: lat-long of the normal.
        u = math.atan2(v[0], -v[2]) / (2 * math.pi) + 0.5
        sphere.vertex(mul(v, r), v, (u, math.acos(max(-1.0, min(1.0, v[1]))) / math.pi))
    sphere.indices = indices
    g.node("sphere", mesh=g.mesh("sphere", [(sphere, mat, True)]))
    g.camera("camera", (0.0, 0.0, 2.0), (0.0, 0.0, 0.0), 40.0)
    g.write_glb(folder, "furnace")
    write_text(os.path.join(folder, "bake.toml"), """\
# White furnace: a Lambert sphere of albedo 0.5 under a constant white sky. Every visible point
# of the (convex) sphere must have radiance == albedo == 0.5 (scenes/generate.py).
scene = "furnace.glb"
mode = "pixel"
width = 128
height = 128
spp = 64
reflections = 2
seed = 0

[environment]
color = [1.0, 1.0, 1.0]

[materials.sphere]
editable = true
family = "diffuse"
""")


# The gallery's and the atrium's light and editable materials (their bake.toml's tail).
STUDIO_KNOT_BUNNY = """\
# Scaled so the lit floor comes out near 0.6-0.8 (the map's irradiance on an upward plane is
# about 14 W/m^2 at intensity 1).
[environment]
map = "../envmaps/studio.exr"
intensity = 0.25

# Glossy: glTF says a dark blue dielectric with roughness 0.387 (ggx, alpha 0.15, Ks 0.04);
# a clearly visible lobe needs a larger Ks (Kd + Ks stays <= 1).
[materials.knot]
editable = true
family = "ggx"
kd = [0.05, 0.12, 0.35]
ks = 0.5
alpha = 0.15

# Diffuse: fully rough in the glTF (-> diffuse), Kd from its base colour.
[materials.bunny]
editable = true
family = "diffuse"
kd = [0.8, 0.4, 0.18]
"""


def gallery(bunny_js):
    """A glossy torus knot and a diffuse bunny on a gridded floor, lit only by a lat-long
    environment map (scenes/envmaps/studio.exr): the scene for the per-vertex mode, so every
    surface is tessellated finely enough for transfer stored at vertices."""
    folder = os.path.join(HERE, "gallery")
    os.makedirs(folder, exist_ok=True)
    g = Gltf()
    floor_mat = g.material("floor", (0.6, 0.6, 0.6))
    # Roughness 0.3873 is GGX alpha 0.15; the config raises Ks from glTF's 0.04 to 0.5.
    knot_mat = g.material("knot", (0.05, 0.12, 0.35), metallic=0.0, roughness=0.3873)
    bunny_mat = g.material("bunny", (0.8, 0.4, 0.18))

    # Floor: 1.4 m square, 96 x 96 grid (1.46 cm spacing) for shadows and colour bleeding.
    F, nf = 0.7, 96
    floor = MeshData()
    grid_quad(floor, (-F, 0, F), (2 * F, 0, 0), (0, 0, -2 * F), nf, nf, (0, 1, 0))
    g.node("floor", mesh=g.mesh("floor", [(floor, floor_mat, True)]))

    # Torus knot (2, 3): 0.09 m knot radius, 3.2 cm tube, 320 x 24 vertices, turned a quarter
    # about Z so one lobe points up and two rest on the floor; standing in the XY plane, then
    # turned 25 degrees about +Y by its node, sunk 1 mm into the floor.
    knot = torus_knot(2, 3, 0.09, 0.032, 320, 24)
    knot.positions = [(-p[1], p[0], p[2]) for p in knot.positions]
    knot.normals = [(-n[1], n[0], n[2]) for n in knot.normals]
    knot_lift = -min(p[1] for p in knot.positions) - 0.001
    g.node("knot", mesh=g.mesh("knot", [(knot, knot_mat, True)]),
           translation=[-0.2, knot_lift, -0.05], rotation=y_rotation_quaternion(25.0))

    # The bunny: two levels of Loop subdivision (1 839 -> 29 354 vertices), scaled to metres
    # (0.026 per native unit, about 0.25 m tall), area-weighted normals, sunk 1 mm.
    positions, indices = load_bunny(bunny_js)
    for _ in range(2):
        positions, indices = loop_subdivide(positions, indices)
    positions = [mul(p, 0.026) for p in positions]
    bunny = MeshData()
    bunny.positions = positions
    bunny.normals = smooth_normals(positions, indices)
    bunny.indices = indices
    bunny_lift = -min(p[1] for p in positions) - 0.001
    g.node("bunny", mesh=g.mesh("bunny", [(bunny, bunny_mat, True)]),
           translation=[0.2, bunny_lift, 0.05], rotation=y_rotation_quaternion(-30.0))

    g.camera("camera", (0.0, 0.4, 0.98), (0.0, 0.15, 0.0), 38.0, aspect=4.0 / 3.0)
    g.write_gltf(folder, "gallery")
    write_text(os.path.join(folder, "bake.toml"), """\
# Gallery: a glossy torus knot and a diffuse bunny on a floor, lit only by the studio
# environment map (scenes/generate.py; map: scenes/envmaps/README.md).
#
# Made for the per-vertex mode (dynamic light, view and materials; docs/vertex.md): 46 483
# vertices. Compressed (the default, docs/vertex.md section 7) the file is about 130 MB and the
# bake needs about 8 GB of memory (dense, `[vertex] compress = false`: 5.7 GB and 13 GB; the
# allocation report says so before tracing); `relight` then renders any view, light and
# material setting. (`width` and `height` are the per-pixel mode's; vertex mode ignores them.)
scene = "gallery.gltf"
mode = "vertex"
width = 160
height = 120
spp = 64
reflections = 2
seed = 0

""" + STUDIO_KNOT_BUNNY)


def atrium(bunny_js):
    """The gallery at the size of the thesis' largest per-vertex scene (131.1K vertices): a
    larger floor and a back wall, a bigger glossy knot, the diffuse bunny and a second,
    non-editable bunny (a stone statue), 130 380 vertices. Every group stays below 36K
    vertices, because a group's dense tensors are held in memory until it is compressed."""
    folder = os.path.join(HERE, "atrium")
    os.makedirs(folder, exist_ok=True)
    g = Gltf()
    floor_mat = g.material("floor", (0.6, 0.6, 0.6))
    wall_mat = g.material("wall", (0.7, 0.68, 0.62))
    knot_mat = g.material("knot", (0.05, 0.12, 0.35), metallic=0.0, roughness=0.3873)
    bunny_mat = g.material("bunny", (0.8, 0.4, 0.18))
    stone_mat = g.material("stone", (0.55, 0.55, 0.5))

    # Floor: 2.4 m square, 188 x 188 grid (1.28 cm spacing): 35 721 vertices.
    F, nf = 1.2, 188
    floor = MeshData()
    grid_quad(floor, (-F, 0, F), (2 * F, 0, 0), (0, 0, -2 * F), nf, nf, (0, 1, 0))
    g.node("floor", mesh=g.mesh("floor", [(floor, floor_mat, True)]))

    # Back wall: 2.4 x 1.2 m at z = -1.2 facing +Z, 100 x 50 grid: 5 151 vertices.
    wall = MeshData()
    grid_quad(wall, (-F, 0, -F), (2 * F, 0, 0), (0, 1.2, 0), 100, 50, (0, 0, 1))
    g.node("wall", mesh=g.mesh("wall", [(wall, wall_mat, True)]))

    # Torus knot (2, 3) twice the gallery's: 0.18 m, 6.4 cm tube, 640 x 48 = 30 720 vertices.
    knot = torus_knot(2, 3, 0.18, 0.064, 640, 48)
    knot.positions = [(-p[1], p[0], p[2]) for p in knot.positions]
    knot.normals = [(-n[1], n[0], n[2]) for n in knot.normals]
    knot_lift = -min(p[1] for p in knot.positions) - 0.001
    g.node("knot", mesh=g.mesh("knot", [(knot, knot_mat, True)]),
           translation=[-0.45, knot_lift, -0.05], rotation=y_rotation_quaternion(25.0))

    # Two bunnies, two levels of Loop subdivision each (29 354 vertices): the editable diffuse
    # one 0.5 m tall, and a 0.4 m stone statue behind, turned away.
    positions, indices = load_bunny(bunny_js)
    for _ in range(2):
        positions, indices = loop_subdivide(positions, indices)
    normals = smooth_normals(positions, indices)
    for name, mat, scale, where, turn in [
            ("bunny", bunny_mat, 0.052, (0.45, 0.15), -30.0),
            ("statue", stone_mat, 0.042, (0.05, -0.65), 160.0)]:
        md = MeshData()
        md.positions = [mul(p, scale) for p in positions]
        md.normals = normals
        md.indices = indices
        lift = -min(p[1] for p in md.positions) - 0.001
        g.node(name, mesh=g.mesh(name, [(md, mat, True)]),
               translation=[where[0], lift, where[1]], rotation=y_rotation_quaternion(turn))

    g.camera("camera", (0.0, 0.85, 2.1), (0.0, 0.25, -0.2), 40.0, aspect=1.0)
    g.write_gltf(folder, "atrium")
    write_text(os.path.join(folder, "bake.toml"), """\
# Atrium: the gallery at the size of the thesis' largest per-vertex scene (130 380 vertices;
# scenes/generate.py): a glossy torus knot and a diffuse bunny (editable), a stone bunny, a
# floor and a back wall, lit only by the studio environment map.
#
# For the per-vertex report's larger scene (docs/report-vertex.md). Compressed (the default) the
# file is about 430 MB; the bake holds one group's dense tensors at a time (the floor's, the
# largest), so its peak memory (about 11 GB) is not far above the gallery's although it has
# nearly three times the vertices; the allocation report says how much before tracing.
# N1 = 32 directions per vertex (half the gallery's) keeps the bake near 7 minutes on two
# idle cores.
scene = "atrium.gltf"
mode = "vertex"
width = 160
height = 160
spp = 32
reflections = 2
seed = 0

""" + STUDIO_KNOT_BUNNY)


def vitrine(bunny_js):
    """The per-vertex mode's test scene, small enough to bake in seconds: a glossy sphere and a
    diffuse bunny (its native 1 839 vertices) on a floor, lit by a lat-long environment map.
    The regression tests bake it and compare relit images with the reference tracer for
    several environments, rotations, cameras and materials."""
    folder = os.path.join(HERE, "vitrine")
    os.makedirs(folder, exist_ok=True)
    g = Gltf()
    floor_mat = g.material("floor", (0.6, 0.6, 0.6))
    sphere_mat = g.material("sphere", (0.1, 0.1, 0.1), metallic=0.0, roughness=0.3162)
    bunny_mat = g.material("bunny", (0.8, 0.4, 0.18))

    # Floor: 1.2 m square, 24 x 24 grid (5 cm spacing).
    F, nf = 0.6, 24
    floor = MeshData()
    grid_quad(floor, (-F, 0, F), (2 * F, 0, 0), (0, 0, -2 * F), nf, nf, (0, 1, 0))
    g.node("floor", mesh=g.mesh("floor", [(floor, floor_mat, True)]))

    # Sphere: icosphere level 3 (642 vertices), radius 0.12 m, exact normals, resting on the
    # floor 1 mm deep.
    verts, indices = icosphere(3)
    r = 0.12
    sphere = MeshData()
    for v in verts:
        sphere.vertex(mul(v, r), v)
    sphere.indices = indices
    g.node("sphere", mesh=g.mesh("sphere", [(sphere, sphere_mat, True)]),
           translation=[-0.17, r - 0.001, 0.0])

    positions, indices = load_bunny(bunny_js)
    positions = [mul(p, 0.022) for p in positions]
    bunny = MeshData()
    bunny.positions = positions
    bunny.normals = smooth_normals(positions, indices)
    bunny.indices = indices
    lift = -min(p[1] for p in positions) - 0.001
    g.node("bunny", mesh=g.mesh("bunny", [(bunny, bunny_mat, True)]),
           translation=[0.15, lift, 0.02], rotation=y_rotation_quaternion(-30.0))

    g.camera("camera", (0.0, 0.35, 0.85), (0.0, 0.1, 0.0), 40.0)
    g.write_gltf(folder, "vitrine")
    write_text(os.path.join(folder, "bake.toml"), """\
# Vitrine: the per-vertex mode's test scene (scenes/generate.py): a glossy GGX sphere and a
# diffuse bunny on a floor under the sky map; about 3K vertices, so it bakes in seconds.
scene = "vitrine.gltf"
mode = "vertex"
width = 128
height = 128
spp = 64
reflections = 2
seed = 0

[environment]
map = "../envmaps/sky.exr"
intensity = 0.25

[materials.sphere]
editable = true
family = "ggx"
kd = [0.1, 0.1, 0.1]
ks = 0.6
alpha = 0.1

[materials.bunny]
editable = true
family = "diffuse"
kd = [0.8, 0.4, 0.18]

# N2 (`[vertex] secondary`) stays at its default 4: T1 also draws one direction in every light
# bin per first hit (`light_bins`, on by default), so the sun's bin no longer depends on a few
# lucky BRDF directions (docs/vertex.md, "Light-bin sampling").
""")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("scenes", nargs="*", default=["cornell", "ring", "furnace", "gallery", "vitrine", "atrium"])
    ap.add_argument("--bunny", help="index.js of the npm package `bunny` (default: reuse the "
                                    "bunny committed in scenes/cornell/cornell.gltf; used by "
                                    "cornell, gallery and atrium)")
    args = ap.parse_args()
    for name in args.scenes:
        if name == "cornell":
            cornell(args.bunny)
        elif name == "ring":
            ring()
        elif name == "furnace":
            furnace()
        elif name == "gallery":
            gallery(args.bunny)
        elif name == "vitrine":
            vitrine(args.bunny)
        elif name == "atrium":
            atrium(args.bunny)
        else:
            sys.exit("unknown scene %r (cornell, ring, furnace, gallery, vitrine, atrium)" % name)
        print("wrote scenes/%s" % name)


if __name__ == "__main__":
    main()
