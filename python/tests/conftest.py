"""Shared fixtures: the repository's scenes, the command-line tools (built once), and two tiny
bakes made through the package itself (cornell per pixel at 64x64 and 4 spp with a rank-4
compressed variant, about 10 s; vitrine per vertex at 4 spp, about a minute on two cores)."""

import os
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))

import prt  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"


@pytest.fixture(scope="session")
def tools():
    """The `relight` and `reference` binaries (release), built if needed."""
    subprocess.run(
        ["cargo", "build", "--release", "--quiet", "-p", "prt-cli", "--bin", "relight",
         "--bin", "reference"],
        cwd=ROOT,
        check=True,
    )
    target = Path(os.environ.get("CARGO_TARGET_DIR", ROOT / "target"))
    return {name: target / "release" / name for name in ("relight", "reference")}


@pytest.fixture(scope="session")
def work(tmp_path_factory):
    return tmp_path_factory.mktemp("prt")


# PRT_PYTEST_BAKES=DIR keeps the two bakes in DIR and reuses them (for working on the tests;
# CI bakes afresh).
BAKES = os.environ.get("PRT_PYTEST_BAKES")


def baked(work, name, **settings):
    out = Path(BAKES) / f"{name}.prtbake" if BAKES else work / f"{name}.prtbake"
    if not out.exists():
        prt.bake(SCENES / name, out=out, **settings)
    return out


@pytest.fixture(scope="session")
def cornell(work):
    """A per-pixel bake of the Cornell box (64x64, 4 spp, compressed variant of rank 4)."""
    return baked(work, "cornell", spp=4, width=64, height=64, compress_rank=4)


@pytest.fixture(scope="session")
def vitrine(work):
    """A per-vertex bake of the vitrine (4 directions per vertex)."""
    # The callback takes the bake's warning about the sky map's negative texels.
    return baked(work, "vitrine", spp=4, checkpoint=False, progress=lambda event: None)


def run(args):
    """Runs a command-line tool; fails the test with its stderr when it fails."""
    done = subprocess.run([str(a) for a in args], capture_output=True, text=True)
    assert done.returncode == 0, f"{args[0]} failed:\n{done.stderr}"
    return done
