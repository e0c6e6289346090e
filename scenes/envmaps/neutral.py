#!/usr/bin/env python3
"""Writes neutral.hdr: the soft, colourless studio light `bake` gives a bare glTF.

A 128 x 64 lat-long map (Radiance RGBE, run-length encoded; the convention of
docs/conventions.md, "Environment maps": row 0 looks up, the centre column down -Z, u = 0.75
along +X), every texel gray (R = G = B, so it tints no material):

* a sky dome, 0.35 at the horizon rising to 0.55 overhead (W m^-2 sr^-1);
* a large soft key light high in front on the left, towards (-0.5, 0.75, 0.45) (a camera
  that frames a scene from +Z, as `bake` does for a glTF without a camera, sees its lit side),
  a Gaussian of 15 degrees angular radius peaking at 8.5;
* a dark gray floor, 0.1, blended into the sky over 3 degrees either side of the horizon.

A white diffuse surface facing up receives 2.8 W/m^2 and so has radiance 0.9 (a PNG's white is
1 at exposure 1); one facing the camera 0.52, one facing away from the key 0.27. The numbers
are in scenes/envmaps/README.md. Python 3, standard library only, deterministic:

    python3 scenes/envmaps/neutral.py [--out scenes/envmaps/neutral.hdr]
"""

import argparse
import math
import os

WIDTH, HEIGHT = 128, 64

SKY_HORIZON, SKY_ZENITH = 0.35, 0.55
FLOOR = 0.1
HORIZON_BLEND = math.radians(3.0)
KEY_DIRECTION = (-0.5, 0.75, 0.45)
KEY_PEAK = 8.5
KEY_RADIUS = math.radians(15.0)


def direction(u, v):
    """The lat-long convention of prt_formats::latlong::uv_to_direction."""
    theta = math.pi * v
    phi = 2.0 * math.pi * (u - 0.5)
    st = math.sin(theta)
    return (st * math.sin(phi), math.cos(theta), -st * math.cos(phi))


def smoothstep(e0, e1, x):
    t = min(max((x - e0) / (e1 - e0), 0.0), 1.0)
    return t * t * (3.0 - 2.0 * t)


def radiance(d):
    kx, ky, kz = KEY_DIRECTION
    n = math.sqrt(kx * kx + ky * ky + kz * kz)
    cos_key = (d[0] * kx + d[1] * ky + d[2] * kz) / n
    angle = math.acos(min(max(cos_key, -1.0), 1.0))
    key = KEY_PEAK * math.exp(-((angle / KEY_RADIUS) ** 2))
    elevation = math.asin(min(max(d[1], -1.0), 1.0))
    sky = SKY_HORIZON + (SKY_ZENITH - SKY_HORIZON) * max(d[1], 0.0)
    up = smoothstep(-HORIZON_BLEND, HORIZON_BLEND, elevation)
    return up * (sky + key) + (1.0 - up) * FLOOR


def rgbe(value):
    """One gray value as Radiance RGBE bytes (Greg Ward's float2rgbe)."""
    if value < 1e-32:
        return bytes(4)
    mantissa, exponent = math.frexp(value)
    m = min(int(mantissa * 256.0), 255)
    return bytes((m, m, m, exponent + 128))


def scanline(pixels):
    """A scanline in the 'new' run-length encoding: per component, literal runs of at most
    128 bytes (no repeat runs: the map is small, and literal runs are valid everywhere)."""
    out = bytearray((2, 2, WIDTH >> 8, WIDTH & 0xFF))
    for c in range(4):
        comp = bytes(p[c] for p in pixels)
        for start in range(0, len(comp), 128):
            chunk = comp[start : start + 128]
            out.append(len(chunk))
            out.extend(chunk)
    return bytes(out)


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default=os.path.join(here, "neutral.hdr"))
    args = parser.parse_args()
    data = bytearray(b"#?RADIANCE\n# neutral studio light, scenes/envmaps/neutral.py\n")
    data += b"FORMAT=32-bit_rle_rgbe\n\n"
    data += b"-Y %d +X %d\n" % (HEIGHT, WIDTH)
    for y in range(HEIGHT):
        row = [
            rgbe(radiance(direction((x + 0.5) / WIDTH, (y + 0.5) / HEIGHT)))
            for x in range(WIDTH)
        ]
        data += scanline(row)
    tmp = args.out + ".tmp"
    with open(tmp, "wb") as f:
        f.write(data)
    os.replace(tmp, args.out)
    print(f"wrote {args.out} ({len(data)} bytes, {WIDTH} x {HEIGHT})")


if __name__ == "__main__":
    main()
