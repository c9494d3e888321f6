#!/usr/bin/env python3
"""Real labelled frames for `skyframe-horizon bench --real`: the Horizon-UAV set.

490 frames (480x480 JPEG) of front-facing UAV video with sky/land masks and a straight-line
label each, MIT licence, (c) 2021 Novelio Putra Indarto
(https://github.com/NovelioPI/horizon-detection-for-uav; the `dataset-slope` variant, mirrored
with its licence note in https://github.com/JuroUhlar/etdh-horizon-detection under
data/horizon_uav_dataset). Not shipped in this repository (105 MB as PNG).

    git clone --depth 1 https://github.com/JuroUhlar/etdh-horizon-detection /tmp/etdh
    python3 tools/horizon/horizon_uav_set.py /tmp/etdh/data/horizon_uav_dataset /tmp/horizon-uav
    skyframe-horizon bench --real /tmp/horizon-uav --only horizon-uav

Writes frame_NNNNNN.png (in label.csv order), camera.toml and truth.csv. The camera is an
assumption, as the set has no calibration: 60 degrees horizontal field of view, principal point
at the centre (the issue's reading of these frames). A label is `y = slope*x + offset*480` in
pixel coordinates (least squares on the mask boundary); in the conventions' terms roll =
atan(-slope), and the pitch follows from the line's height at the principal point. Every frame
shows the horizon (visible = 1). Needs opencv-python-headless (JPEG decoding).
"""
import csv
import os
import sys

import cv2

import real_set


def main():
    if len(sys.argv) != 3:
        sys.exit("usage: horizon_uav_set.py DATASET_DIR (with images/ and label.csv) OUT_DIR")
    source, out = sys.argv[1], sys.argv[2]
    try:
        with open(os.path.join(source, "label.csv"), newline="") as f:
            rows = list(csv.DictReader(f))
    except OSError as e:
        sys.exit(f"horizon_uav_set: {e}")
    width = height = 480
    writer = real_set.Writer(out, width, height)
    for row in rows:
        path = os.path.join(source, "images", row["filename"])
        image = cv2.imread(path, cv2.IMREAD_COLOR)
        if image is None or image.shape[:2] != (height, width):
            sys.exit(f"horizon_uav_set: {path}: not a {width}x{height} image")
        writer.add(image, float(row["slope"]), float(row["offset"]) * height)
    writer.finish()


if __name__ == "__main__":
    main()
