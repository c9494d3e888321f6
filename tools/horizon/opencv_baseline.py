#!/usr/bin/env python3
"""OpenCV baseline for `skyframe-horizon bench`: the textbook horizon detector.

For each directory given (frames frame_*.png, camera.toml), writes opencv.csv with
`frame,roll_deg,pitch_deg,ms`. Pipeline, one thread (cv2.setNumThreads(1)):
grey -> 5x5 Gaussian blur -> Canny(30, 90) -> edge points -> cv2.undistortPoints with the
camera's k1, k2 (skipped when both are 0) -> HoughLines (1 px, 1 degree) -> the global maximum
-> the darker side is the ground -> roll and pitch by the skyframe conventions' horizon line
`sin(roll)*x + cos(roll)*y = tan(pitch)` (normalised undistorted coordinates, ground where the
left side is larger). `ms` covers everything after decoding the PNG.

Needs opencv-python-headless 4.x (pinned by the bench: 4.10.0.84) and numpy.
"""
import math
import os
import sys
import time
import tomllib

import cv2
import numpy as np

cv2.setNumThreads(1)


def load_camera(directory):
    with open(os.path.join(directory, "camera.toml"), "rb") as f:
        cam = tomllib.load(f)
    K = np.array([[cam["fx"], 0, cam["cx"]], [0, cam["fy"], cam["cy"]], [0, 0, 1]], dtype=np.float64)
    dist = np.array([cam.get("k1", 0.0), cam.get("k2", 0.0), 0.0, 0.0], dtype=np.float64)
    return cam, K, dist


class Detector:
    def __init__(self, cam, K, dist, width, height):
        self.cam, self.K, self.dist = cam, K, dist
        self.distorted = bool(dist[0] != 0.0 or dist[1] != 0.0)
        self.width, self.height = width, height
        # Rasterise undistorted points with a margin: barrel correction moves them outwards.
        self.margin = width // 2 if self.distorted else 0
        self.threshold = max(20, width // 5)
        # A grid of sample points (every 4th pixel) in normalised undistorted coordinates, for
        # deciding which side of the line is the ground.
        gy, gx = np.mgrid[2:height:4, 2:width:4]
        self.grid_pixels = (gy.ravel(), gx.ravel())
        pts = np.stack([gx.ravel(), gy.ravel()], axis=1).astype(np.float64).reshape(-1, 1, 2)
        norm = cv2.undistortPoints(pts, K, dist).reshape(-1, 2)
        self.grid_x, self.grid_y = norm[:, 0], norm[:, 1]

    def detect(self, bgr):
        grey = cv2.cvtColor(bgr, cv2.COLOR_BGR2GRAY)
        edges = cv2.Canny(cv2.GaussianBlur(grey, (5, 5), 0), 30, 90)
        m = self.margin
        if self.distorted:
            ys, xs = np.nonzero(edges)
            if len(xs) == 0:
                return None
            pts = np.stack([xs, ys], axis=1).astype(np.float32).reshape(-1, 1, 2)
            und = cv2.undistortPoints(pts, self.K, self.dist, P=self.K).reshape(-1, 2)
            xi = np.round(und[:, 0]).astype(np.int64) + m
            yi = np.round(und[:, 1]).astype(np.int64) + m
            h, w = self.height + 2 * m, self.width + 2 * m
            keep = (xi >= 0) & (xi < w) & (yi >= 0) & (yi < h)
            canvas = np.zeros((h, w), dtype=np.uint8)
            canvas[yi[keep], xi[keep]] = 255
            edges = canvas
        lines = cv2.HoughLines(edges, 1, np.pi / 180, self.threshold)
        if lines is None:
            return None
        rho, theta = lines[0][0]  # OpenCV returns lines by decreasing votes: the global maximum
        # u*cos(t) + v*sin(t) = rho in (margin-shifted) undistorted pixels -> normalised coords.
        ct, st = math.cos(theta), math.sin(theta)
        cx, cy = self.cam["cx"] + m, self.cam["cy"] + m
        a, b = self.cam["fx"] * ct, self.cam["fy"] * st
        c = rho - cx * ct - cy * st
        n = math.hypot(a, b)
        nx, ny, d = a / n, b / n, c / n
        side = self.grid_x * nx + self.grid_y * ny > d
        values = grey[self.grid_pixels]
        if side.all() or (~side).all():
            return None
        # The darker side is the ground.
        if values[side].mean() < values[~side].mean():
            roll, offset = math.atan2(nx, ny), d
        else:
            roll, offset = math.atan2(-nx, -ny), -d
        return math.degrees(roll), math.degrees(math.atan(offset))


def run(directory):
    cam, K, dist = load_camera(directory)
    frames = sorted(f for f in os.listdir(directory) if f.startswith("frame_") and f.endswith(".png"))
    detector = None
    rows = ["frame,roll_deg,pitch_deg,ms"]
    for index, name in enumerate(frames):
        bgr = cv2.imread(os.path.join(directory, name), cv2.IMREAD_COLOR)
        if bgr is None:
            sys.exit(f"opencv_baseline: {directory}/{name}: cannot read")
        if detector is None:
            detector = Detector(cam, K, dist, bgr.shape[1], bgr.shape[0])
        start = time.perf_counter()
        result = detector.detect(bgr)
        ms = (time.perf_counter() - start) * 1e3
        if result is None:
            rows.append(f"{index},,,{ms:.4f}")
        else:
            rows.append(f"{index},{result[0]:.4f},{result[1]:.4f},{ms:.4f}")
    with open(os.path.join(directory, "opencv.csv"), "w") as f:
        f.write("\n".join(rows) + "\n")


def main():
    if not cv2.__version__.startswith("4."):
        sys.exit(f"opencv_baseline: OpenCV {cv2.__version__}, want 4.x")
    for directory in sys.argv[1:]:
        run(directory)


if __name__ == "__main__":
    main()
