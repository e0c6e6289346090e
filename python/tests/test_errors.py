"""Bad input raises the right exception of the PrtError hierarchy, with the library's message
naming what is wrong, and changes nothing."""

import numpy as np
import pytest

import prt
from conftest import ROOT, SCENES


def test_hierarchy():
    assert issubclass(prt.FileError, prt.PrtError) and issubclass(prt.FileError, OSError)
    assert issubclass(prt.ConfigError, prt.PrtError) and issubclass(prt.ConfigError, ValueError)
    assert issubclass(prt.ParameterError, prt.PrtError)
    assert issubclass(prt.ParameterError, ValueError)
    assert issubclass(prt.Cancelled, prt.PrtError)


def test_files(work):
    missing = work / "missing.prtbake"
    with pytest.raises(prt.FileError, match="missing.prtbake") as e:
        prt.open(missing)
    assert isinstance(e.value, OSError)
    # A file that is no bake (a scene's glTF), and a truncated bake.
    with pytest.raises(prt.FileError, match="cornell.gltf"):
        prt.open(SCENES / "cornell" / "cornell.gltf")
    with pytest.raises(prt.FileError, match="no_config"):
        prt.bake(work / "no_config.toml")
    with pytest.raises(prt.FileError, match="no_scene"):
        prt.reference(work / "no_scene")


def test_truncated_bake(cornell, work):
    cut = work / "cut.prtbake"
    cut.write_bytes(cornell.read_bytes()[:5000])
    with pytest.raises(prt.FileError, match="cut.prtbake"):
        prt.open(cut)


def test_materials_and_parameters(cornell):
    r = prt.open(cornell)
    before = r.render()
    cases = [
        (dict(material="nosuch", kd=0.5), r"unknown material 'nosuch'.*bunny"),
        (dict(material="white", kd=0.5), r"'white' is not editable.*bunny, tall_box"),
        (dict(material="bunny", alpha=0.3), r"'bunny' is blinn-phong: it has no parameter 'alpha'"),
        (dict(material="bunny", rougness=0.3), r"unknown parameter 'rougness'.*kd, ks"),
        (dict(material="bunny", shininess=-5.0), r"shininess = -5 is outside.*\[0, 1000000\]"),
        (dict(material="tall_box", alpha=2.0), r"alpha = 2 is outside.*\[0.0001, 1\]"),
        (dict(material="bunny", kd=(0.5, -0.1, 0.5)), r"kd = \[0.5, -0.1, 0.5\] is outside"),
        (dict(material="bunny", kd=(0.5, float("nan"), 0.5)), r"kd = \[0.5, NaN, 0.5\]"),
        (dict(material="bunny", kd=(0.5, 0.5)), r"kd = \(0.5, 0.5\): give a colour"),
        (dict(material="bunny", shininess="shiny"), r"shininess = shiny: give a number"),
    ]
    for kwargs, message in cases:
        with pytest.raises(prt.ParameterError, match=message):
            r.set(**kwargs)
    # All or none: a valid kd with an invalid shininess sets neither.
    with pytest.raises(prt.ParameterError):
        r.set("bunny", kd=0.9, shininess=-1.0)
    assert {m.name: m for m in r.materials}["bunny"].params["kd"].value == (0.55, 0.5, 0.45)
    assert np.array_equal(r.render(), before)
    with pytest.raises(prt.ParameterError, match="variant \"low\""):
        r.variant = "low"


def test_output_arrays(cornell):
    r = prt.open(cornell)
    w, h = r.size
    cases = [
        (np.zeros((w, h + 1, 3), np.float32), r"shape is \[64, 65, 3\]"),
        (np.zeros((h, w, 3), np.float64), "dtype is float64"),
        (np.zeros((h, w, 6), np.float32)[:, :, ::2], "not C-contiguous"),
        ([[0.0] * 3] * (w * h), "not a numpy array"),
    ]
    read_only = np.zeros((h, w, 3), np.float32)
    read_only.flags.writeable = False
    cases.append((read_only, "read-only"))
    for out, message in cases:
        with pytest.raises(prt.ParameterError, match=message):
            r.render(out=out)


def test_environments_cameras_sizes(vitrine, work):
    r = prt.open(vitrine)
    r.size = (32, 32)
    before = r.render()
    nan = np.ones((8, 16, 3))
    nan[3, 5, 1] = np.nan
    cases = [
        (lambda: setattr(r, "environment", np.ones((8, 16, 4))), r"shape \[8, 16, 4\]"),
        (lambda: setattr(r, "environment", np.ones((8, 16))), r"shape \[8, 16\]"),
        (lambda: setattr(r, "environment", np.ones((8, 16, 3), np.int32)), "dtype int32"),
        (lambda: setattr(r, "environment", nan), "NaN or infinite.*column 5, row 3"),
        (lambda: setattr(r, "environment", np.ones((0, 16, 3))), "environment map"),
        (lambda: setattr(r, "environment_intensity", -1.0), "intensity"),
        (lambda: setattr(r, "environment_rotation", float("inf")), "rotation"),
        (lambda: setattr(r, "size", (0, 32)), "0x32"),
        (lambda: prt.Camera(eye=(0, 1, 3), target=(0, 1, 3), fov=40), "eye and target must differ"),
        (lambda: prt.Camera(eye=(0, 1, 3), target=(0, 0, 0), fov=180), r"fov 180 must be in \(0, 180\)"),
        # The eye at the sphere's centre.
        (lambda: setattr(r, "camera", prt.Camera(eye=(-0.17, 0.12, 0), target=(1, 0, 0), fov=40)),
         "inside 'sphere'"),
    ]
    for act, message in cases:
        with pytest.raises(prt.ParameterError, match=message):
            act()
    with pytest.raises(prt.FileError, match="nowhere.exr"):
        r.environment = work / "nowhere.exr"
    assert np.array_equal(r.render(), before)


def test_bake_settings(work):
    with pytest.raises(prt.ConfigError, match="width, compress_rank applies to per-pixel"):
        prt.bake(SCENES / "vitrine", out=work / "x.prtbake", width=8, compress_rank=2)
    with pytest.raises(prt.ConfigError, match="resume applies to per-vertex"):
        prt.bake(SCENES / "cornell", out=work / "x.prtbake", resume=True)
    with pytest.raises(prt.ParameterError, match="precision \"f64\""):
        prt.bake(SCENES / "cornell", out=work / "x.prtbake", precision="f64")
    bad = work / "bad.toml"
    bad.write_text('scene = "cornell.gltf"\nspp = "many"\n')
    with pytest.raises(prt.ConfigError, match="bad.toml"):
        prt.bake(bad)
    assert not (work / "x.prtbake").exists()


def test_reference_settings(cornell):
    with pytest.raises(prt.ParameterError, match="nosuch"):
        prt.reference(SCENES / "cornell", set={"nosuch": {"kd": 0.5}}, spp=1, width=4, height=4)
    with pytest.raises(prt.ParameterError, match="not a map"):
        prt.reference(SCENES / "cornell", env_rotation=30.0, spp=1, width=4, height=4)
    with pytest.raises(prt.ParameterError, match="at least 1"):
        prt.reference(SCENES / "cornell", spp=0, width=4, height=4)
    with pytest.raises(prt.ParameterError, match="give env too"):
        prt.reference(SCENES / "cornell", env_intensity=2.0, spp=1, width=4, height=4)
    with pytest.raises(prt.ParameterError, match="reference"):
        prt.compare(np.zeros((4, 4, 3)), np.zeros((4, 5, 3)))
    assert ROOT.is_dir()
