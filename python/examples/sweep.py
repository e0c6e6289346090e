"""The worked example of docs/python.md: bake the Cornell box per pixel, sweep the tall box's
GGX roughness, render each setting and its ground truth, and plot the images with the error
against the reference; the figure goes to docs/img/python-sweep.png.

    pip install ./python matplotlib tqdm
    python python/examples/sweep.py            # about a minute on two cores
"""

import argparse
from pathlib import Path

import matplotlib

matplotlib.use("Agg")  # no display needed: the figure is written to a file
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import prt  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
SCENE = ROOT / "scenes" / "cornell"


def display(image, exposure=1.0):
    """Linear radiance to something to look at (clamped, gamma 2.2)."""
    return np.clip(image * exposure, 0.0, 1.0) ** (1 / 2.2)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=128, help="image width and height")
    parser.add_argument("--spp", type=int, default=16, help="the bake's samples per pixel")
    parser.add_argument("--reference-spp", type=int, default=64)
    parser.add_argument("--work", type=Path, default=ROOT / "target" / "python-example")
    parser.add_argument("--figure", type=Path, default=ROOT / "docs" / "img" / "python-sweep.png")
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)

    try:
        progress = prt.TqdmProgress()
    except ImportError:
        progress = prt.PrintProgress()

    # 1. Bake once: the materials stay editable in the bake file.
    bake = args.work / "cornell.prtbake"
    summary = prt.bake(SCENE, out=bake, width=args.size, height=args.size, spp=args.spp,
                       progress=progress)
    print(f"baked {summary['output']} ({summary['file_bytes'] / 1e6:.1f} MB) "
          f"in {summary['seconds']:.1f} s")

    # 2. Open it and look at what can be edited.
    r = prt.open(bake)
    box = next(m for m in r.materials if m.name == "tall_box")
    alpha = box.params["alpha"]
    print(f"tall_box: {box.family}, alpha = {alpha.value}, accepted {alpha.range}, "
          f"baked for {alpha.sampled}")

    # 3. Sweep the roughness: relight (milliseconds), render the truth (seconds), compare.
    alphas = [0.05, 0.2, 0.5, 1.0]
    fig, axes = plt.subplots(3, len(alphas), figsize=(3 * len(alphas), 9.4))
    for column, a in enumerate(alphas):
        r.set("tall_box", alpha=a)
        image = r.render()
        truth = prt.reference(SCENE, like=r, spp=args.reference_spp, progress=progress)
        c = prt.compare(image, truth)
        print(f"alpha {a}: relative L2 {c.relative_l2:.4f}, mean difference {c.z_mean:+.2f} "
              "standard errors")
        error = np.abs(image - truth).mean(axis=2)
        axes[0, column].imshow(display(image))
        axes[0, column].set_title(f"relit, alpha = {a}")
        axes[1, column].imshow(display(truth))
        axes[1, column].set_title(f"reference, {args.reference_spp} spp")
        shown = axes[2, column].imshow(error, cmap="magma", vmin=0.0, vmax=0.2)
        axes[2, column].set_title(f"|error|: L2 {c.relative_l2:.3f}, z {c.z_mean:+.1f}")
    for ax in axes.flat:
        ax.set_axis_off()
    fig.colorbar(shown, ax=axes[2, :], shrink=0.8, label="mean |relit - reference| (RGB)")
    args.figure.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.figure, dpi=60, bbox_inches="tight")
    print(f"wrote {args.figure}")


if __name__ == "__main__":
    main()
