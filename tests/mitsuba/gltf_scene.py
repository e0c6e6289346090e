"""Reads a glTF 2.0 scene the way the baker does (docs/conventions.md), with numpy only:
world-space triangles per primitive, the glTF materials, and the first perspective camera.

Used by compare.py to hand Mitsuba exactly the geometry the baker traces. It covers what the
project's scenes use (TRIANGLES primitives, indexed or not, with or without normals, node
hierarchies with TRS or matrix transforms, .gltf with .bin or data URIs, and .glb); anything
else it refuses loudly rather than guessing, since a silent difference here would show up as a
mismatch that is not the baker's fault.
"""

import base64
import json
import os
import struct

import numpy as np

COMPONENT = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16,
             5125: np.uint32, 5126: np.float32}
COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}
TRIANGLES = 4


def load(path):
    """Returns (json document, list of buffer bytes) of a .gltf or .glb file."""
    raw = open(path, "rb").read()
    if raw[:4] == b"glTF":
        # GLB: 12-byte header, then a JSON chunk and an optional BIN chunk.
        json_len, = struct.unpack_from("<I", raw, 12)
        doc = json.loads(raw[20:20 + json_len])
        off = 20 + json_len
        bin_chunk = b""
        if off + 8 <= len(raw):
            bin_len, = struct.unpack_from("<I", raw, off)
            bin_chunk = raw[off + 8:off + 8 + bin_len]
    else:
        doc = json.loads(raw)
        bin_chunk = None
    buffers = []
    for buf in doc.get("buffers", []):
        uri = buf.get("uri")
        if uri is None:
            buffers.append(bin_chunk)
        elif uri.startswith("data:"):
            buffers.append(base64.b64decode(uri.split(",", 1)[1]))
        else:
            buffers.append(open(os.path.join(os.path.dirname(path), uri), "rb").read())
    return doc, buffers


def accessor(doc, buffers, index):
    """The accessor's elements as a float64 (count, components) array (strides honoured)."""
    acc = doc["accessors"][index]
    if "sparse" in acc:
        raise NotImplementedError("sparse accessors")
    n = COMPONENTS[acc["type"]]
    dtype = np.dtype(COMPONENT[acc["componentType"]]).newbyteorder("<")
    view = doc["bufferViews"][acc["bufferView"]]
    data = buffers[view["buffer"]]
    start = view.get("byteOffset", 0) + acc.get("byteOffset", 0)
    stride = view.get("byteStride", n * dtype.itemsize)
    count = acc["count"]
    out = np.empty((count, n), np.float64)
    for c in range(n):
        out[:, c] = np.ndarray((count,), dtype, data, start + c * dtype.itemsize, (stride,))
    if acc.get("normalized"):
        out /= float(np.iinfo(dtype).max)
    return out


def node_matrix(node):
    """The node's local 4x4 transform (glTF: matrix column-major, or T * R * S)."""
    if "matrix" in node:
        return np.array(node["matrix"], np.float64).reshape(4, 4).T
    x, y, z, w = node.get("rotation", [0.0, 0.0, 0.0, 1.0])
    r = np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])
    m = np.eye(4)
    m[:3, :3] = r * np.array(node.get("scale", [1.0, 1.0, 1.0]))[None, :]
    m[:3, 3] = node.get("translation", [0.0, 0.0, 0.0])
    return m


def walk(doc):
    """(node, world matrix) for every node of the default scene, depth first in file order."""
    scene = doc["scenes"][doc.get("scene", 0)]
    stack = [(i, np.eye(4)) for i in reversed(scene["nodes"])]
    while stack:
        i, parent = stack.pop()
        node = doc["nodes"][i]
        world = parent @ node_matrix(node)
        yield node, world
        for child in reversed(node.get("children", [])):
            stack.append((child, world))


class Primitive:
    """One TRIANGLES primitive in world space: positions (n, 3), normals (n, 3) or None,
    triangles (m, 3) counter-clockwise seen from the front, and its glTF material index (None
    for none)."""

    def __init__(self, mesh_name, positions, normals, triangles, material):
        self.mesh_name = mesh_name
        self.positions = positions
        self.normals = normals
        self.triangles = triangles
        self.material = material


def primitives(doc, buffers):
    out = []
    for node, world in walk(doc):
        if "mesh" not in node:
            continue
        mesh = doc["meshes"][node["mesh"]]
        linear = world[:3, :3]
        flip = np.linalg.det(linear) < 0  # a mirror reverses the winding (glTF spec)
        normal_matrix = np.linalg.inv(linear).T
        for prim in mesh["primitives"]:
            if prim.get("mode", TRIANGLES) != TRIANGLES:
                continue  # the baker skips these too (with a warning)
            if "targets" in prim:
                raise NotImplementedError("morph targets")
            attrs = prim["attributes"]
            pos = accessor(doc, buffers, attrs["POSITION"])
            pos = pos @ linear.T + world[:3, 3]
            nrm = None
            if "NORMAL" in attrs:
                nrm = accessor(doc, buffers, attrs["NORMAL"]) @ normal_matrix.T
                nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
            if "indices" in prim:
                idx = accessor(doc, buffers, prim["indices"])[:, 0].astype(np.int64)
            else:
                idx = np.arange(len(pos))
            tris = idx.reshape(-1, 3)
            if flip:
                tris = tris[:, [0, 2, 1]]
            out.append(Primitive(mesh.get("name", "mesh%d" % node["mesh"]), pos, nrm, tris,
                                 prim.get("material")))
    return out


def materials(doc):
    """The glTF materials' factors: name, base colour, metallic, roughness, emission (RGB,
    emissiveFactor x KHR_materials_emissive_strength). Textures are refused: the comparison
    maps factors only."""
    out = []
    for i, m in enumerate(doc.get("materials", [])):
        pbr = m.get("pbrMetallicRoughness", {})
        textured = ("baseColorTexture" in pbr or "metallicRoughnessTexture" in pbr
                    or "emissiveTexture" in m or "normalTexture" in m)
        if textured:
            raise NotImplementedError("textured material %r" % m.get("name"))
        strength = m.get("extensions", {}).get("KHR_materials_emissive_strength", {}) \
                    .get("emissiveStrength", 1.0)
        out.append({
            "name": m.get("name", "material%d" % i),
            "base": list(pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0])[:3]),
            "metallic": pbr.get("metallicFactor", 1.0),
            "roughness": pbr.get("roughnessFactor", 1.0),
            "emission": [c * strength for c in m.get("emissiveFactor", [0.0, 0.0, 0.0])],
        })
    return out


def camera(doc):
    """The first perspective camera met depth first: position, forward, up (re-orthonormalized
    as the baker does) and the vertical field of view in radians."""
    for node, world in walk(doc):
        if "camera" not in node:
            continue
        cam = doc["cameras"][node["camera"]]
        if cam.get("type") != "perspective":
            continue
        position = world[:3, 3]
        forward = world[:3, :3] @ np.array([0.0, 0.0, -1.0])
        forward /= np.linalg.norm(forward)
        up0 = world[:3, :3] @ np.array([0.0, 1.0, 0.0])
        right = np.cross(forward, up0)
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        return {"position": position, "forward": forward, "up": up,
                "yfov": cam["perspective"]["yfov"]}
    raise ValueError("no perspective camera")


def write_ply(path, positions, normals, triangles):
    """Binary little-endian PLY (float32 vertices, optional normals, int32 faces)."""
    n = len(positions)
    head = ["ply", "format binary_little_endian 1.0", "element vertex %d" % n,
            "property float x", "property float y", "property float z"]
    cols = [positions]
    if normals is not None:
        head += ["property float nx", "property float ny", "property float nz"]
        cols.append(normals)
    head += ["element face %d" % len(triangles), "property list uchar int vertex_indices",
             "end_header"]
    verts = np.ascontiguousarray(np.hstack(cols), dtype="<f4")
    faces = np.empty(len(triangles), dtype=[("n", "u1"), ("i", "<i4", (3,))])
    faces["n"] = 3
    faces["i"] = triangles
    with open(path, "wb") as f:
        f.write(("\n".join(head) + "\n").encode())
        f.write(verts.tobytes())
        f.write(faces.tobytes())


def point_lights(doc):
    """KHR_lights_punctual point lights: world position and intensity x colour (W/sr per
    channel, 1 cd = 1 W/sr as docs/conventions.md says). Spot and directional lights are
    refused (no scene compared here has one)."""
    lights = doc.get("extensions", {}).get("KHR_lights_punctual", {}).get("lights", [])
    out = []
    for node, world in walk(doc):
        ext = node.get("extensions", {}).get("KHR_lights_punctual")
        if ext is None:
            continue
        light = lights[ext["light"]]
        if light.get("type") != "point":
            raise NotImplementedError("%s light" % light.get("type"))
        colour = light.get("color", [1.0, 1.0, 1.0])
        out.append({"position": world[:3, 3],
                    "intensity": [c * light.get("intensity", 1.0) for c in colour]})
    return out
