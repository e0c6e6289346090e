"""The ground truth from Python: `prt.reference` is the `reference` tool's image bit for bit,
`like=` gives the settings of a relighter, and `prt.compare` measures an image against it."""

import numpy as np
import pytest

import prt
from conftest import SCENES, run
from exr import read_exr
from test_relight import same_bits

STUDIO = SCENES / "envmaps" / "studio.exr"


def test_pixel_reference_is_the_cli_image(tools, work):
    image = prt.reference(
        SCENES / "cornell",
        spp=2, seed=7, width=40, height=32,
        set={"bunny": {"kd": (0.8, 0.2, 0.2), "shininess": 120.0}, "tall_box": {"alpha": 0.3}},
    )
    assert image.shape == (32, 40, 3) and image.dtype == np.float32
    exr = work / "cornell-reference.exr"
    run([tools["reference"], SCENES / "cornell", "--spp", "2", "--seed", "7", "--width", "40",
         "--height", "32", "--set", "bunny.kd=0.8,0.2,0.2", "--set", "bunny.shininess=120",
         "--set", "tall_box.alpha=0.3", "--out", exr])
    assert same_bits(image, read_exr(exr))


def test_vertex_reference_is_the_cli_image(tools, work):
    camera = prt.Camera(eye=(0.5, 0.4, 0.7), target=(0.0, 0.1, 0.0), fov=45.0)
    image = prt.reference(
        SCENES / "vitrine", spp=2, width=48, height=32, env=STUDIO, env_intensity=1.5,
        env_rotation=75.0, camera=camera, set={"sphere": {"alpha": 0.25}},
    )
    exr = work / "vitrine-reference.exr"
    run([tools["reference"], SCENES / "vitrine", "--spp", "2", "--width", "48", "--height", "32",
         "--env", STUDIO, "--env-intensity", "1.5", "--env-rotate", "75",
         "--camera", "eye=0.5,0.4,0.7 target=0,0.1,0 fov=45", "--set", "sphere.alpha=0.25",
         "--out", exr])
    assert same_bits(image, read_exr(exr))
    # An environment handed over as an array is the file's.
    sky = read_exr(work / "vitrine-reference.exr")  # any float image will do as a map
    a = prt.reference(SCENES / "vitrine", spp=1, width=16, height=16, env=sky)
    path = work / "reference-sky.exr"
    prt.write_image(path, sky)
    assert same_bits(a, prt.reference(SCENES / "vitrine", spp=1, width=16, height=16, env=path))


def test_like_takes_every_setting_of_a_relighter(cornell, vitrine):
    r = prt.open(cornell)
    r.set("bunny", kd=(0.8, 0.2, 0.2), shininess=120.0)
    r.set("tall_box", alpha=0.3)
    explicit = prt.reference(
        SCENES / "cornell", spp=1, width=64, height=64,
        set={"bunny": {"kd": (0.8, 0.2, 0.2), "shininess": 120.0}, "tall_box": {"alpha": 0.3}},
    )
    assert same_bits(prt.reference(SCENES / "cornell", like=r, spp=1), explicit)

    v = prt.open(vitrine)
    v.environment = STUDIO
    v.environment_rotation = 75.0
    v.environment_intensity = 1.5
    v.camera = prt.Camera(eye=(0.5, 0.4, 0.7), target=(0.0, 0.1, 0.0), fov=45.0)
    v.size = (48, 32)
    v.set("sphere", alpha=0.25)
    explicit = prt.reference(
        SCENES / "vitrine", spp=1, width=48, height=32, env=STUDIO, env_intensity=1.5,
        env_rotation=75.0, camera=v.camera, set={"sphere": {"alpha": 0.25}},
    )
    assert same_bits(prt.reference(SCENES / "vitrine", like=v, spp=1), explicit)
    # Keywords replace what `like` gives.
    turned = prt.reference(SCENES / "vitrine", like=v, spp=1, env_rotation=-75.0)
    assert not same_bits(turned, explicit)
    # A bake left as opened: the config's own settings (its environment, rotation, camera).
    fresh = prt.open(vitrine)
    fresh.size = (48, 32)
    assert same_bits(
        prt.reference(SCENES / "vitrine", like=fresh, spp=1),
        prt.reference(SCENES / "vitrine", spp=1, width=48, height=32),
    )


def test_compare_measures_error_and_bias():
    rng = np.random.default_rng(1)
    truth = rng.uniform(0.5, 1.5, size=(40, 50, 3))
    same = prt.compare(truth, truth)
    assert same.relative_l2 == 0.0 and same.z == (0.0, 0.0, 0.0) and same.z_mean == 0.0
    # Noise of standard deviation 0.1 per pixel: the mean difference's standard error is
    # 0.1 / sqrt(2000) within a few per cent, and its z is a standard normal draw.
    noisy = truth + rng.normal(0.0, 0.1, size=truth.shape)
    c = prt.compare(noisy, truth)
    assert c.standard_error == pytest.approx((0.1 / np.sqrt(2000),) * 3, rel=0.05)
    assert all(abs(z) < 4 for z in c.z)
    expected_l2 = np.sqrt(((noisy - truth) ** 2).sum() / (truth ** 2).sum())
    assert c.relative_l2 == pytest.approx(expected_l2, rel=1e-6)
    # A 2 % bias in red only: red is off by many standard errors, the others are not.
    biased = noisy * np.array([1.02, 1.0, 1.0])
    c = prt.compare(biased, truth)
    assert c.mean_difference[0] == pytest.approx(0.02 * truth[..., 0].mean(), abs=5e-3)
    assert c.z[0] > 6 and abs(c.z[1]) < 4 and abs(c.z[2]) < 4


def test_relit_bake_against_its_reference(cornell):
    """A per-pixel bake is an unbiased estimate of the reference (up to its basis' projection
    error, under 1 % here): the mean difference lies within noise; a 5 % brighter or darker
    image is caught (z about +7 and -9 measured)."""
    r = prt.open(cornell)
    r.set("bunny", kd=(0.8, 0.2, 0.2), shininess=120.0)
    r.set("tall_box", alpha=0.3)
    image = r.render()
    truth = prt.reference(SCENES / "cornell", like=r, spp=64)
    assert abs(prt.compare(image, truth).z_mean) < 4
    assert prt.compare(image * 1.05, truth).z_mean > 4
    assert prt.compare(image * 0.95, truth).z_mean < -4
