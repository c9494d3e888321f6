"""What the real-set converters (horizon_uav_set.py, infml_set.py) share: the directory that
`skyframe-horizon bench --real` reads, for a set whose labels are straight lines in pixels
and whose camera is not calibrated.

The camera is an assumption: 60 degrees horizontal field of view, square pixels, principal
point at the centre. A label y = slope * x + offset (pixels, centres at whole numbers) is, in
the conventions' terms, roll = atan(-slope) and a pitch from the line's height at the
principal point; every labelled frame shows the horizon (visible = 1).
"""
import math
import os

import cv2

FIELD_OF_VIEW_DEG = 60.0


class Writer:
    """camera.toml now, frame_NNNNNN.png per `add`, truth.csv at `finish`."""

    def __init__(self, out, width, height):
        self.out, self.width, self.height = out, width, height
        self.fx = self.fy = (width / 2) / math.tan(math.radians(FIELD_OF_VIEW_DEG / 2))
        self.cx, self.cy = (width - 1) / 2, (height - 1) / 2
        os.makedirs(out, exist_ok=True)
        with open(os.path.join(out, "camera.toml"), "w") as f:
            f.write(
                f"width = {width}\nheight = {height}\nfx = {self.fx}\nfy = {self.fy}\n"
                f"cx = {self.cx}\ncy = {self.cy}\nk1 = 0.0\nk2 = 0.0\n"
            )
        self.truth = ["frame,roll_deg,pitch_deg,visible"]

    def add(self, image, slope, offset_px):
        """Writes the next frame and its truth from the labelled line."""
        i = len(self.truth) - 1
        cv2.imwrite(os.path.join(self.out, f"frame_{i:06d}.png"), image)
        roll = math.atan2(-slope, 1.0)
        pitch = math.atan(math.cos(roll) * (slope * self.cx + offset_px - self.cy) / self.fy)
        self.truth.append(f"{i},{math.degrees(roll):.4f},{math.degrees(pitch):.4f},1")

    def finish(self):
        with open(os.path.join(self.out, "truth.csv"), "w") as f:
            f.write("\n".join(self.truth) + "\n")
        print(f"{len(self.truth) - 1} frames in {self.out}")
