#!/usr/bin/env python3
"""Passes a labelled frame set through a camera-and-link chain: a Bayer sensor, an analogue
video link and a low-quality JPEG link, each optional.

The tuning generators (`synth`, `terrain`) draw their own sensor noise and block coding; the
held-out `aerial` generator's `mixed` class showed what they lack: a real demosaicking's
colour noise, an analogue link's line jitter and libjpeg at half resolution. This script
applies those kinds of artefact to frames the bench kept (`skyframe-horizon bench --keep`),
so that the detector can be tuned on them without looking at `aerial`'s frames. It is written
from the kinds of artefact `aerial_set.py` uses (same parameter ranges, same OpenCV codecs), so
those artefacts are no longer held out; `aerial`'s world, light and optics still are.

    python3 tools/horizon/camera_chain.py IN OUT --stages bayer,analogue,jpeg-half --seed 7

IN and OUT are set directories (frame_NNNNNN.png, camera.toml, truth.csv); OUT gets the
same camera and truth (the chain moves no horizon) and the frames passed through the stages,
in the order bayer → analogue → jpeg. A frame set and seed always give the same frames.
"""

import argparse
import math
import os
import shutil
import sys

STAGES = ("none", "bayer", "analogue", "jpeg", "jpeg-half")


def fail(message):
    print(f"camera_chain.py: {message}", file=sys.stderr)
    sys.exit(1)


try:
    import cv2
    import numpy as np
except ImportError as e:
    fail(f"needs numpy and OpenCV ({e})")


def linear(x):
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def srgb(x):
    x = np.clip(x, 0, 1)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def bayer(rgb, rng):
    """An RGGB sensor at 300-900 electrons full scale: shot, read and column noise on the
    mosaic, OpenCV's demosaicking, the sRGB curve and an unsharp mask."""
    h, w = rgb.shape[:2]
    electrons = rng.uniform(300, 900)
    x = linear(rgb)
    mosaic = np.empty((h, w))
    mosaic[0::2, 0::2] = x[0::2, 0::2, 0]
    mosaic[0::2, 1::2] = x[0::2, 1::2, 1]
    mosaic[1::2, 0::2] = x[1::2, 0::2, 1]
    mosaic[1::2, 1::2] = x[1::2, 1::2, 2]
    signal = rng.poisson(mosaic * electrons).astype(np.float64)
    signal += rng.normal(0, rng.uniform(2, 6), mosaic.shape)
    signal += rng.normal(0, rng.uniform(0.5, 2.5), (1, w))
    raw = np.round(np.clip(signal / electrons, 0, 1) * 65535).astype(np.uint16)
    # OpenCV names a mosaic by its second row's first two sites: RGGB is its BayerBG.
    out = srgb(cv2.cvtColor(raw, cv2.COLOR_BayerBG2RGB).astype(np.float64) / 65535)
    blurred = cv2.GaussianBlur(out, (0, 0), 1.0)
    return np.clip(out + 0.6 * (out - blurred), 0, 1)


def analogue(rgb, rng, i, pattern):
    """Line-timebase jitter, a chirped co-channel pattern (the flight's amplitude, period and
    angle), a rolling hum bar and snow."""
    amplitude, period, angle = pattern
    h, w = rgb.shape[:2]
    jitter = np.cumsum(rng.normal(0, 0.35, h))
    jitter -= np.convolve(jitter, np.ones(15) / 15, mode="same")
    mapx = (np.arange(w)[None, :] + jitter[:, None]).astype(np.float32)
    mapy = np.repeat(np.arange(h, dtype=np.float32)[:, None], w, 1)
    out = cv2.remap(rgb.astype(np.float32), mapx, mapy, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    out = out.astype(np.float64)
    vv, uu = np.mgrid[0:h, 0:w].astype(np.float64)
    along = uu * math.cos(angle) + vv * math.sin(angle)
    phase = 2 * math.pi * along / period + 1.2 * math.pi * (vv / h) ** 2 + i * 1.7
    hum = 0.08 * np.sin(2 * math.pi * (vv / h * 0.8 + i * 0.13))
    out = out + (amplitude * np.sin(phase) + hum)[..., None]
    snow = rng.random((h, w)) < 0.002
    out[snow] = rng.random((int(snow.sum()), 1))
    return np.clip(out, 0, 1)


def jpeg(bgr, rng, previous, half):
    """OpenCV's libjpeg at quality 15-40 (4:2:0), at half resolution if `half`; lost 16-row
    slices concealed with the previous frame's, a slice torn sideways now and then."""
    h, w = bgr.shape[:2]
    quality = int(rng.uniform(15, 40))
    src = cv2.resize(bgr, (w // 2, h // 2), interpolation=cv2.INTER_AREA) if half else bgr
    ok, data = cv2.imencode(".jpg", src, [cv2.IMWRITE_JPEG_QUALITY, quality])
    if not ok:
        fail("OpenCV could not encode a JPEG")
    out = cv2.imdecode(data, cv2.IMREAD_COLOR)
    if half:
        out = cv2.resize(out, (w, h), interpolation=cv2.INTER_LINEAR)
    for top in range(0, h, 16):
        if previous is not None and rng.random() < 0.05:
            out[top : top + 16] = previous[top : top + 16]
        elif rng.random() < 0.03:
            shift = int(rng.integers(8, 64)) * (1 if rng.random() < 0.5 else -1)
            out[top : top + 16] = np.roll(out[top : top + 16], shift, axis=1)
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
    a = p.parse_args()
    stages = set(a.stages.split(","))
    unknown = stages - set(STAGES)
    if unknown:
        fail(f"unknown stage {sorted(unknown)[0]!r} (stages: {', '.join(STAGES)})")
    if "jpeg" in stages and "jpeg-half" in stages:
        fail("jpeg and jpeg-half are one link: take one")
    for name in ("camera.toml", "truth.csv"):
        if not os.path.isfile(os.path.join(a.input, name)):
            fail(f"{os.path.join(a.input, name)}: missing (not a set directory)")
    names = sorted(n for n in os.listdir(a.input) if n.startswith("frame_") and n.endswith(".png"))
    if not names:
        fail(f"{a.input}: no frame_NNNNNN.png frames")
    os.makedirs(a.output, exist_ok=True)
    for name in ("camera.toml", "truth.csv"):
        shutil.copy(os.path.join(a.input, name), os.path.join(a.output, name))

    rng = np.random.default_rng(a.seed)
    # One co-channel pattern per flight, at 0.4 of the interference class's amplitude (as
    # aerial's mixed links).
    pattern = (rng.uniform(0.03, 0.12) * 0.4, rng.uniform(4, 40), rng.uniform(-math.pi, math.pi))
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
            rgb = analogue(rgb, rng, i, pattern)
        out = np.clip(np.round(rgb[..., ::-1] * 255), 0, 255).astype(np.uint8)
        if "jpeg" in stages or "jpeg-half" in stages:
            out = jpeg(out, rng, previous, "jpeg-half" in stages)
            previous = out
        if not cv2.imwrite(os.path.join(a.output, name), out):
            fail(f"{os.path.join(a.output, name)}: could not be written")


if __name__ == "__main__":
    main()
