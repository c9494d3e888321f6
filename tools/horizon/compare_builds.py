#!/usr/bin/env python3
"""Two builds of `skyframe-horizon` on the same sets: do they answer alike, and which is faster.

A change meant to make the detector faster without changing what it reads is checked here:
both builds run `detect` on every set (a directory of frames, with its `camera.toml` when it
has one), each frame's answer is compared (roll, pitch and confidence as `detect` prints them,
to 0.001), and the detector's own time a frame (`detect`'s `ms` column: the detector only, not
the decoding) is gathered per frame size. The builds take turns set by set, and each run
starts with the other one, so a machine that slows down or speeds up during the comparison
weighs on both alike:

    python3 tools/horizon/compare_builds.py --baseline OLD --candidate NEW [--runs 5] SET...

It prints one JSON document: the frames that differ (the first few of them, with both answers),
and per frame size each build's median over the runs of its median and of its mean frame
time, with the ratio baseline / candidate (above 1: the candidate is faster), and the median
over the runs of each run's own ratio of medians (`speedup_median_paired`: a run that was slow
for both builds moves it least).

Exit codes: 0 compared (with --require-same: and every answer alike), 1 answers differ under
--require-same, 2 bad input or a build that failed (the set or build and why, on one line).
"""

import argparse
import json
import math
import os
import signal
import statistics
import subprocess
import sys
import tomllib

# Differing frames listed in full in the report (all are counted).
SHOWN = 20


def fail(message):
    print(f"compare_builds: {message}", file=sys.stderr)
    sys.exit(2)


def camera_file(set_dir):
    """The set's camera file, or None where it has none."""
    camera = os.path.join(set_dir, "camera.toml")
    return camera if os.path.exists(camera) else None


def frame_size(set_dir):
    """`WIDTHxHEIGHT` from the set's camera file, or `unknown` without one."""
    camera = camera_file(set_dir)
    if camera is None:
        return "unknown"
    try:
        with open(camera, "rb") as f:
            doc = tomllib.load(f)
        width, height = doc.get("width"), doc.get("height")
    except (OSError, ValueError) as e:
        fail(f"{camera}: {type(e).__name__}: {e}")
    if not (isinstance(width, int) and isinstance(height, int)):
        return "unknown"
    return f"{width}x{height}"


def detect(build, set_dir):
    """One build's answers on one set: [(answer, ms)] in frame order."""
    command = [build, "detect", set_dir]
    camera = camera_file(set_dir)
    if camera is not None:
        command += ["--camera", camera]
    try:
        done = subprocess.run(command, capture_output=True, check=False)
    except OSError as e:
        fail(f"{build}: {e.strerror or e}")
    if done.returncode != 0:
        why = done.stderr.decode("utf-8", "replace").strip().splitlines()
        fail(f"{build} on {set_dir}: exit {done.returncode}: {why[-1] if why else 'no message'}")
    rows = []
    lines = done.stdout.decode("utf-8", "replace").splitlines()
    for number, line in enumerate(lines[1:], start=2):
        fields = line.split(",")
        try:
            if len(fields) != 5:
                raise ValueError(f"{len(fields)} fields")
            ms = float(fields[4])
            if not math.isfinite(ms):
                raise ValueError(f"time {fields[4]!r}")
        except ValueError as e:
            fail(f"{build} on {set_dir}: output line {number} unreadable ({e})")
        rows.append((",".join(fields[1:4]), ms))
    if not rows:
        fail(f"{build} on {set_dir}: no frames")
    return rows


def summary(per_run):
    """Median over the runs of each run's median and mean frame time."""
    medians = [statistics.median(ms) for ms in per_run]
    means = [statistics.fmean(ms) for ms in per_run]
    return {
        "ms_median": statistics.median(medians),
        "ms_mean": statistics.median(means),
        "ms_median_of_each_run": medians,
    }


def ratio(baseline, candidate):
    """baseline / candidate, or None where the candidate took no time."""
    return baseline / candidate if candidate > 0 else None


def paired(baseline, candidate):
    """The median over the runs of baseline / candidate (None where a candidate took 0)."""
    ratios = [ratio(b, c) for b, c in zip(baseline, candidate)]
    return None if None in ratios else statistics.median(ratios)


def main():
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    parser = argparse.ArgumentParser(
        description="Compare two builds of skyframe-horizon frame by frame: answers and time."
    )
    parser.add_argument("--baseline", required=True, help="the build compared against")
    parser.add_argument("--candidate", required=True, help="the build being checked")
    parser.add_argument("--runs", type=int, default=3, help="turns of both builds over every set")
    parser.add_argument(
        "--require-same", action="store_true", help="exit 1 when any frame's answer differs"
    )
    parser.add_argument("sets", nargs="+", help="directories of frames")
    args = parser.parse_args()
    if args.runs < 1:
        fail("--runs must be at least 1")
    for build in (args.baseline, args.candidate):
        if not (os.path.isfile(build) and os.access(build, os.X_OK)):
            fail(f"{build}: not an executable file")
    for set_dir in args.sets:
        if not os.path.isdir(set_dir):
            fail(f"{set_dir}: not a directory")
    sizes = {set_dir: frame_size(set_dir) for set_dir in args.sets}
    builds = {"baseline": args.baseline, "candidate": args.candidate}
    # times[build][size][run]: every frame's ms of that run.
    times = {name: {} for name in builds}
    frames = 0
    differing = []
    for run in range(args.runs):
        order = ["baseline", "candidate"] if run % 2 == 0 else ["candidate", "baseline"]
        for set_dir in args.sets:
            answers = {}
            for name in order:
                rows = detect(builds[name], set_dir)
                answers[name] = [answer for answer, _ in rows]
                runs = times[name].setdefault(sizes[set_dir], [[] for _ in range(args.runs)])
                runs[run].extend(ms for _, ms in rows)
            if run > 0:
                continue
            base, cand = answers["baseline"], answers["candidate"]
            frames += max(len(base), len(cand))
            for frame in range(max(len(base), len(cand))):
                a = base[frame] if frame < len(base) else None
                b = cand[frame] if frame < len(cand) else None
                if a != b:
                    differing.append({"set": set_dir, "frame": frame, "baseline": a, "candidate": b})
    speed = []
    for size in sorted(times["baseline"]):
        base, cand = summary(times["baseline"][size]), summary(times["candidate"][size])
        speed.append(
            {
                "size": size,
                "frames_per_run": len(times["baseline"][size][0]),
                "baseline": base,
                "candidate": cand,
                "speedup_median": ratio(base["ms_median"], cand["ms_median"]),
                "speedup_mean": ratio(base["ms_mean"], cand["ms_mean"]),
                # Each run's two medians were taken minutes apart at most: their ratio, run by
                # run, is not moved by a machine that is slower in one run than in another.
                "speedup_median_paired": paired(
                    base["ms_median_of_each_run"], cand["ms_median_of_each_run"]
                ),
            }
        )
    report = {
        "baseline": args.baseline,
        "candidate": args.candidate,
        "runs": args.runs,
        "sets": len(args.sets),
        "frames": frames,
        "answers_differ": len(differing),
        "differing": differing[:SHOWN],
        "speed": speed,
    }
    print(json.dumps(report, indent=2))
    if args.require_same and differing:
        sys.exit(1)


if __name__ == "__main__":
    main()
