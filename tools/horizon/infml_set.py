#!/usr/bin/env python3
"""Real labelled frames for `skyframe-horizon bench --real`: a maritime infrared sequence.

466 frames (384x288, thermal, grey) of one sequence over open sea, the test clip of the
InfML-HDD infrared horizon set (Fu, Li, Zhao, "Real-Time Infrared Horizon Detection in Maritime
and Land Environments Based on Hyper-Laplace Filter and CNN", IEEE TIM 2023), in
https://github.com/FJsRepo/InfML-HDD under data/test_set (MIT licence, the repository's
LICENSE.new, (c) 2022 FuJian; no separate licence is given for the data). Not shipped in this repository. Not what skyframe's
airplanes see (a visible-light camera over land), so it tells how the detector carries to
another kind of frame: no colour, a sea whose waves are textured like fields, a sky that may be
the darker side.

    git clone --depth 1 https://github.com/FJsRepo/InfML-HDD /tmp/infml-hdd
    python3 tools/horizon/infml_set.py /tmp/infml-hdd/data/test_set /tmp/infml
    skyframe-horizon bench --real /tmp/infml --only infml

Writes frame_NNNNNN.png (grey, in the label file's order), camera.toml and truth.csv. The
camera is an assumption, as the set has no calibration: 60 degrees horizontal field of view
(as for the Horizon-UAV set), principal point at the centre; roll does not depend on it, the
pitch scales with it. A label is 13 points of the horizon (x every 32 px, y cut to whole
pixels: the set's converter, utils/SSL_to_json.py, took int() of each, so the line is their
least-squares fit moved down by half a pixel); as with Horizon-UAV roll = atan(-slope) and
the pitch follows from the line's height at the principal point. Every frame shows the horizon
(visible = 1). Needs opencv-python-headless (PNG decoding).
"""
import json
import os
import sys

import cv2

import real_set

LABELS = "test_data_5_test.json"


def fit_line(xs, ys):
    """Least-squares y = slope * x + offset through the points."""
    n = len(xs)
    mx, my = sum(xs) / n, sum(ys) / n
    sxx = sum((x - mx) ** 2 for x in xs)
    if n < 2 or sxx == 0:
        raise ValueError("fewer than two distinct x")
    slope = sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx
    return slope, my - slope * mx


def main():
    if len(sys.argv) != 3:
        sys.exit(f"usage: infml_set.py TEST_SET_DIR (with {LABELS} and clips/) OUT_DIR")
    source, out = sys.argv[1], sys.argv[2]
    labels_path = os.path.join(source, LABELS)
    rows = []
    try:
        with open(labels_path) as f:
            for number, line in enumerate(f, 1):
                if line.strip():
                    try:
                        rows.append(json.loads(line))
                    except json.JSONDecodeError as e:
                        sys.exit(f"infml_set: {labels_path}:{number}: {e}")
    except OSError as e:
        sys.exit(f"infml_set: {e}")
    width, height = 384, 288
    writer = real_set.Writer(out, width, height)
    for i, row in enumerate(rows):
        try:
            path = os.path.join(source, row["raw_file"])
            slope, offset = fit_line(row["x_coordinate"], row["y_coordinate"])
            # int() cut each y down to a whole pixel: by half a pixel on average.
            offset += 0.5
        except (KeyError, TypeError, ValueError) as e:
            sys.exit(f"infml_set: {labels_path}: label {i + 1}: {e}")
        image = cv2.imread(path, cv2.IMREAD_GRAYSCALE)
        if image is None or image.shape[:2] != (height, width):
            sys.exit(f"infml_set: {path}: not a {width}x{height} image")
        writer.add(image, slope, offset)
    writer.finish()


if __name__ == "__main__":
    main()
