#!/usr/bin/env python3
"""Passes a labelled frame set through an H.264 video link that loses slices: FFmpeg's
libx264 at a low quality, some slices dropped from the stream, FFmpeg's decoder concealing
what is missing.

This is the second link of another construction (see camera_chain.py, which the detector is
tuned on): a real encoder with motion-compensated prediction, 4:2:0 and its deblocking filter,
slices as the encoder cuts them, and a real decoder's concealment. It is only scored, never
tuned on (docs/horizon.md).

    python3 tools/horizon/h264_link.py IN OUT --crf 36 --loss 0.03 --seed 1

IN and OUT are set directories (frame_NNNNNN.png, camera.toml, truth.csv); OUT gets the same
camera and truth. Needs PyAV (`pip install av`, whose wheels bundle FFmpeg with libx264).
"""

import argparse
import os
from fractions import Fraction

from labelled_set import copy_labels, fail, frame_names

try:
    import av
    import cv2
    import numpy as np
except ImportError as e:
    fail(f"needs PyAV, numpy and OpenCV ({e})")


def nal_units(data):
    """The Annex B stream `data` cut at its start codes: (start code, NAL unit) pairs."""
    units, i, n = [], 0, len(data)
    starts = []
    while True:
        j = data.find(b"\x00\x00\x01", i)
        if j < 0:
            break
        k = j - 1 if j > 0 and data[j - 1] == 0 else j
        starts.append((k, j + 3))
        i = j + 3
    for idx, (k, body) in enumerate(starts):
        end = starts[idx + 1][0] if idx + 1 < len(starts) else n
        units.append((data[k:body], data[body:end]))
    return units


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("input", help="set directory: frame_NNNNNN.png, camera.toml, truth.csv")
    p.add_argument("output", help="directory to write the passed set to (created)")
    p.add_argument("--crf", type=int, default=36, help="libx264's constant rate factor (%(default)s)")
    p.add_argument("--slices", type=int, default=8, help="slices per frame (%(default)s)")
    p.add_argument("--loss", type=float, default=0.03, help="share of slices lost (%(default)s)")
    p.add_argument("--seed", type=int, default=0, help="which slices are lost")
    a = p.parse_args()
    names = frame_names(a.input)
    frames = []
    for name in names:
        bgr = cv2.imread(os.path.join(a.input, name), cv2.IMREAD_COLOR)
        if bgr is None:
            fail(f"{os.path.join(a.input, name)}: not a readable PNG")
        frames.append(bgr)
    h, w = frames[0].shape[:2]
    if w % 2 or h % 2 or any(f.shape[:2] != (h, w) for f in frames):
        fail(f"{a.input}: frames must share one even size")
    copy_labels(a.input, a.output)

    encoder = av.CodecContext.create("libx264", "w")
    encoder.width, encoder.height, encoder.pix_fmt = w, h, "yuv420p"
    encoder.time_base = Fraction(1, 2)  # frames 0.5 s apart, as the sets' flights
    encoder.options = {
        "preset": "veryfast",
        "tune": "zerolatency",
        "crf": str(a.crf),
        "x264-params": f"slices={a.slices}:keyint=30:bframes=0:repeat-headers=1",
    }
    decoder = av.CodecContext.create("h264", "r")
    rng = np.random.default_rng(a.seed)
    decoded = []

    def deliver(packets):
        for packet in packets:
            kept = bytearray()
            for start, unit in nal_units(bytes(packet)):
                kind = unit[0] & 0x1F if unit else 0
                if kind in (1, 5) and rng.random() < a.loss:
                    continue  # a slice lost on the link
                kept += start + unit
            for frame in decoder.decode(av.Packet(bytes(kept))):
                decoded.append(frame.to_ndarray(format="bgr24"))

    for i, bgr in enumerate(frames):
        frame = av.VideoFrame.from_ndarray(bgr, format="bgr24")
        frame.pts = i
        deliver(encoder.encode(frame))
    deliver(encoder.encode(None))
    for frame in decoder.decode(None):
        decoded.append(frame.to_ndarray(format="bgr24"))
    if len(decoded) != len(frames):
        fail(f"the decoder gave {len(decoded)} frames for {len(frames)}")
    for name, bgr in zip(names, decoded):
        if not cv2.imwrite(os.path.join(a.output, name), bgr):
            fail(f"{os.path.join(a.output, name)}: could not be written")


if __name__ == "__main__":
    main()
