#!/usr/bin/env python3
"""Passes a labelled frame set through a camera-and-link chain: a Bayer sensor, an analogue
video link and a low-quality JPEG link, each optional.

The analogue link is `analogue` (at 0.4 of the interference class's amplitude, as aerial's
mixed links) or `interference` (the same link at the interference class's full amplitude).

The tuning generators (`synth`, `terrain`) draw their own sensor noise and block coding; the
held-out `aerial` generator's `mixed` class showed what they lack: a real demosaicking's
colour noise, an analogue link's line jitter and libjpeg at half resolution. This script
applies those kinds of artefact to frames the bench kept (`skyframe-horizon bench --keep`),
so that the detector can be tuned on them without looking at `aerial`'s frames. It is written
with `aerial_set.py`'s own artefact functions (the mixed class's parameter ranges), so those
artefacts are no longer held out; `aerial`'s world, light and optics still are.

    python3 tools/horizon/camera_chain.py IN OUT --stages bayer,analogue,jpeg-half --seed 7

IN and OUT are set directories (frame_NNNNNN.png, camera.toml, truth.csv); OUT gets the
same camera and truth (the chain moves no horizon) and the frames passed through the stages,
in the order bayer → analogue → jpeg. A frame set and seed always give the same frames.
"""

import argparse
import math
import os

from labelled_set import copy_labels, fail, frame_names

STAGES = ("none", "bayer", "analogue", "interference", "jpeg", "jpeg-half")

try:
    import cv2
    import numpy as np

    # The artefacts themselves are aerial's (same directory): one implementation of each.
    import aerial_set
except ImportError as e:
    fail(f"needs numpy and OpenCV ({e})")


def linear(x):
    """sRGB values in [0, 1] back to linear light."""
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def bayer(rgb, rng):
    """An RGGB sensor at 300-900 electrons full scale (aerial's, on the frame's linear light)."""
    return aerial_set.sensor_noise(linear(rgb), rng, electrons=rng.uniform(300, 900))


def jpeg(bgr, rng, previous, half, quality):
    """libjpeg at a quality drawn from `quality` (lowest, highest), full or half resolution,
    then aerial's lost and torn slices."""
    out = aerial_set.jpeg_round_trip(bgr, int(rng.uniform(*quality)), half)
    aerial_set.lose_slices(out, rng, previous)
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("input", help="set directory: frame_NNNNNN.png, camera.toml, truth.csv")
    p.add_argument("output", help="directory to write the passed set to (created)")
    p.add_argument(
        "--stages",
        default="bayer,analogue,jpeg-half",
        help=f"comma-separated, of {', '.join(STAGES)} (default: %(default)s)",
    )
    p.add_argument("--seed", type=int, default=0, help="the chain's random stream")
    p.add_argument(
        "--jpeg-quality",
        default="15,40",
        help="the JPEG link's quality range LOWEST,HIGHEST (default %(default)s, the mixed "
        "class's links; aerial's transmission class codes at 4,22)",
    )
    a = p.parse_args()
    try:
        quality = tuple(int(q) for q in a.jpeg_quality.split(","))
    except ValueError:
        quality = ()
    if len(quality) != 2 or not 1 <= quality[0] <= quality[1] <= 100:
        fail(f"--jpeg-quality {a.jpeg_quality!r}: want LOWEST,HIGHEST within 1-100")
    stages = set(a.stages.split(","))
    unknown = stages - set(STAGES)
    if unknown:
        fail(f"unknown stage {sorted(unknown)[0]!r} (stages: {', '.join(STAGES)})")
    if "jpeg" in stages and "jpeg-half" in stages:
        fail("jpeg and jpeg-half are one link: take one")
    if "analogue" in stages and "interference" in stages:
        fail("analogue and interference are one link: take one")
    names = frame_names(a.input)
    copy_labels(a.input, a.output)

    rng = np.random.default_rng(a.seed)
    # One co-channel pattern per flight, at 0.4 of the interference class's amplitude (as
    # aerial's mixed links).
    pattern = (rng.uniform(0.03, 0.12) * 0.4, rng.uniform(4, 40), rng.uniform(-math.pi, math.pi))
    # `interference`: the same link at the interference class's full amplitude.
    strong = (pattern[0] / 0.4, *pattern[1:])
    previous = None
    for i, name in enumerate(names):
        path = os.path.join(a.input, name)
        bgr = cv2.imread(path, cv2.IMREAD_COLOR)
        if bgr is None:
            fail(f"{path}: not a readable PNG")
        rgb = bgr[..., ::-1].astype(np.float64) / 255
        if "bayer" in stages:
            rgb = bayer(rgb, rng)
        if "analogue" in stages:
            rgb = aerial_set.analogue(rgb, rng, i, *pattern)
        if "interference" in stages:
            rgb = aerial_set.analogue(rgb, rng, i, *strong)
        out = np.clip(np.round(rgb[..., ::-1] * 255), 0, 255).astype(np.uint8)
        if "jpeg" in stages or "jpeg-half" in stages:
            try:
                out = jpeg(out, rng, previous, "jpeg-half" in stages, quality)
            except RuntimeError as e:
                fail(str(e))
            previous = out
        if not cv2.imwrite(os.path.join(a.output, name), out):
            fail(f"{os.path.join(a.output, name)}: could not be written")


if __name__ == "__main__":
    main()
