"""Relighting from Python against the `relight` command-line tool, bit for bit: every kind
of parameter, both kinds of bake, both per-pixel variants; the arrays render() returns."""

import numpy as np
import pytest

import prt
from conftest import SCENES, run
from exr import read_exr


def same_bits(a, b):
    """Whether two float32 images are identical bit for bit (NaN and -0 included)."""
    return a.shape == b.shape and np.array_equal(
        np.ascontiguousarray(a, dtype=np.float32).view(np.uint32),
        np.ascontiguousarray(b, dtype=np.float32).view(np.uint32),
    )


PIXEL_EDITS = {
    "bunny": {"kd": (0.8, 0.2, 0.2), "ks": 0.4, "shininess": 120.0},
    "tall_box": {"kd": (0.3, 0.5, 0.7), "ks": (0.5, 0.4, 0.3), "alpha": 0.3},
}


def set_args(edits):
    args = []
    for material, params in edits.items():
        for name, value in params.items():
            text = ",".join(map(str, value)) if isinstance(value, tuple) else str(value)
            args += ["--set", f"{material}.{name}={text}"]
    return args


@pytest.mark.parametrize("variant", ["full", "compressed"])
def test_pixel_render_is_the_cli_image(cornell, tools, work, variant):
    r = prt.open(cornell)
    assert isinstance(r, prt.PixelRelighter) and r.kind == "pixel"
    assert r.has_compressed
    r.variant = variant
    for material, params in PIXEL_EDITS.items():
        r.set(material, **params)
    image = r.render()
    exr = work / f"cornell-{variant}.exr"
    flags = ["--compressed"] if variant == "compressed" else []
    run([tools["relight"], cornell, *set_args(PIXEL_EDITS), *flags, "--out", exr])
    cli = read_exr(exr)
    assert same_bits(image, cli), f"max difference {np.abs(image - cli).max()}"
    # The edits changed the image (a render ignoring them would pass the comparison only if
    # the tool ignored them too).
    assert not same_bits(image, prt.open(cornell).render())


def test_materials_list_families_values_and_ranges(cornell):
    r = prt.open(cornell)
    by_name = {m.name: m for m in r.materials}
    assert list(by_name) == ["white", "red", "green", "light", "bunny", "tall_box"]
    bunny, box, white = by_name["bunny"], by_name["tall_box"], by_name["white"]
    assert (bunny.family, bunny.editable) == ("blinn-phong", True)
    assert (box.family, box.editable) == ("ggx", True)
    assert (white.family, white.editable, list(white.params)) == ("diffuse", False, ["kd"])
    assert list(bunny.params) == ["kd", "ks", "shininess"]
    assert list(box.params) == ["kd", "ks", "alpha"]
    # The config's values, as written there.
    assert bunny.params["kd"].value == (0.55, 0.5, 0.45)
    assert bunny.params["shininess"].value == 60.0
    assert box.params["alpha"].value == 0.15
    # Accepted ranges: colours >= 0, the lobe parameter its family's; sampled ranges.
    assert bunny.params["kd"].range == (0.0, float("inf"))
    assert box.params["alpha"].range == (0.0001, 1.0)
    assert box.params["alpha"].sampled == (0.02, 1.0)
    assert bunny.params["shininess"].sampled == (1.0, 200.0)
    # Setting reads back; outside the sampled range it is accepted and marked clamped.
    r.set("bunny", kd=0.25, shininess=500)
    bunny = {m.name: m for m in r.materials}["bunny"]
    assert bunny.params["kd"].value == (0.25, 0.25, 0.25)
    assert bunny.params["shininess"].value == 500.0 and bunny.params["shininess"].clamped
    assert "bunny" in repr(bunny) and "500" in repr(bunny.params["shininess"])


def vertex_settings(r):
    r.environment = SCENES / "envmaps" / "studio.exr"
    r.environment_rotation = 75.0
    r.environment_intensity = 1.5
    r.camera = prt.Camera(eye=(0.5, 0.4, 0.7), target=(0.0, 0.1, 0.0), fov=45.0)
    r.size = (96, 64)
    r.set("sphere", kd=(0.2, 0.1, 0.05), ks=0.5, alpha=0.25)
    r.set("bunny", kd=(0.3, 0.6, 0.2))


VERTEX_ARGS = [
    "--env", SCENES / "envmaps" / "studio.exr", "--env-rotate", "75", "--env-intensity", "1.5",
    "--camera", "eye=0.5,0.4,0.7 target=0,0.1,0 fov=45", "--width", "96", "--height", "64",
    "--set", "sphere.kd=0.2,0.1,0.05", "--set", "sphere.ks=0.5", "--set", "sphere.alpha=0.25",
    "--set", "bunny.kd=0.3,0.6,0.2",
]


def test_vertex_render_is_the_cli_image(vitrine, tools, work):
    r = prt.open(vitrine)
    assert isinstance(r, prt.VertexRelighter) and r.kind == "vertex"
    vertex_settings(r)
    assert r.size == (96, 64)
    assert r.environment_rotation == 75.0 and r.environment_intensity == 1.5
    assert r.camera.fov == pytest.approx(45.0, abs=1e-5)
    image = r.render()
    assert image.shape == (64, 96, 3)
    exr = work / "vitrine.exr"
    run([tools["relight"], vitrine, *VERTEX_ARGS, "--out", exr])
    cli = read_exr(exr)
    assert same_bits(image, cli), f"max difference {np.abs(image - cli).max()}"
    # The studio's lamp is a compact light: off, the image is the tool's with the flag.
    assert r.compact_lights
    r.compact_lights = False
    assert not r.compact_lights
    basis_only = r.render()
    exr_off = work / "vitrine-no-compact-lights.exr"
    run([tools["relight"], vitrine, *VERTEX_ARGS, "--no-compact-lights", "--out", exr_off])
    assert same_bits(basis_only, read_exr(exr_off))
    assert not same_bits(basis_only, cli)
    # Silhouettes are antialiased: off, the image is the tool's with the flag.
    assert r.antialias
    r.antialias = False
    assert not r.antialias
    centres = r.render()
    exr_centres = work / "vitrine-no-antialias.exr"
    run([tools["relight"], vitrine, *VERTEX_ARGS, "--no-compact-lights", "--no-antialias",
         "--out", exr_centres])
    assert same_bits(centres, read_exr(exr_centres))
    assert not same_bits(centres, basis_only)
    # Each setting reaches the image: undoing any one of them changes it.
    for undo in (
        lambda v: setattr(v, "compact_lights", False),
        lambda v: setattr(v, "antialias", False),
        lambda v: setattr(v, "environment_rotation", 0.0),
        lambda v: setattr(v, "environment_intensity", 1.0),
        lambda v: setattr(v, "camera", v.camera.orbited(10.0)),
        lambda v: v.set("sphere", alpha=0.1),
        lambda v: v.set("bunny", kd=0.5),
        lambda v: setattr(v, "environment", SCENES / "envmaps" / "sky.exr"),
    ):
        fresh = prt.open(vitrine)
        vertex_settings(fresh)
        undo(fresh)
        assert not same_bits(fresh.render(), cli)


def synthetic_sky(height=32, width=64):
    """A lat-long map: a blue gradient, a warm sun, and a few negative texels (clamped to 0
    by every reader)."""
    theta = (np.arange(height) + 0.5) / height * np.pi
    phi = (np.arange(width) + 0.5) / width * 2 * np.pi
    sky = np.zeros((height, width, 3))
    sky[...] = np.cos(theta)[:, None, None].clip(0) * np.array([0.3, 0.5, 1.0])
    sky[4:6, 40:42] = (40.0, 30.0, 20.0)
    sky[20, 3] = (-0.5, 0.2, 0.1)
    sky += 0.05 * np.sin(3 * phi)[None, :, None] ** 2
    return sky


def test_environment_array_is_the_map_file(vitrine, tools, work):
    sky = synthetic_sky()
    path = work / "synthetic-sky.exr"
    prt.write_image(path, sky)
    assert same_bits(read_exr(path), sky.astype(np.float32))
    r = prt.open(vitrine)
    r.size = (64, 48)
    assert r.set_environment(sky) == 1  # the negative texel, clamped
    from_array = r.render()
    assert same_bits(r.environment, np.maximum(sky, 0).astype(np.float32))
    r.environment = path
    assert same_bits(r.render(), from_array)
    exr = work / "vitrine-synthetic.exr"
    run([tools["relight"], vitrine, "--env", path, "--width", "64", "--height", "48", "--out", exr])
    assert same_bits(read_exr(exr), from_array)


def test_render_returns_a_new_writable_c_contiguous_array_or_fills_out(cornell, vitrine):
    for path in (cornell, vitrine):
        r = prt.open(path)
        w, h = r.size
        a, b = r.render(), r.render()
        for image in (a, b):
            assert isinstance(image, np.ndarray) and image.dtype == np.float32
            assert image.shape == (h, w, 3)
            assert image.flags["C_CONTIGUOUS"] and image.flags["WRITEABLE"]
            assert image.flags["OWNDATA"]
        assert not np.shares_memory(a, b) and same_bits(a, b)
        assert np.isfinite(a).all() and a.max() > 0
        # Into a caller's array: the same object, every value written.
        out = np.full((h, w, 3), np.nan, dtype=np.float32)
        assert r.render(out=out) is out
        assert same_bits(out, a)
    # A per-vertex size change gives arrays of the new shape, width along axis 1.
    r.size = (40, 24)
    assert r.render().shape == (24, 40, 3)


def test_camera_accessors(vitrine):
    c = prt.Camera(eye=(0, 1, 3), target=(0, 1, 0), fov=40)
    assert c.eye == (0.0, 1.0, 3.0) and c.forward == (0.0, 0.0, -1.0)
    assert c.right == (1.0, 0.0, 0.0) and c.up == (0.0, 1.0, 0.0)
    turned = c.orbited(90)
    assert turned.eye == pytest.approx((3.0, 1.0, 0.0), abs=1e-6)
    assert turned.forward == pytest.approx((-1.0, 0.0, 0.0), abs=1e-6)
    r = prt.open(vitrine)
    assert r.camera == r.default_camera
    assert r.environment.shape == (256, 512, 3) and r.environment.dtype == np.float32
