#!/usr/bin/env python3
"""Pool several `skyframe-horizon bench --json` reports into one table per set.

Each held-out `aerial` seed is benched on its own (`bench --real DIR ...`, one report per
seed); this adds the reports up set by set (`clean_320`, `mixed_640`, ...), so that the
issue's targets can be read for the detector as it stands over every seed at once:

    python3 tools/horizon/pool_bench.py /tmp/aer_123.json /tmp/aer_124.json [--json]

Shares are pooled over frames, not averaged over seeds: within 2° over the frames with a
visible horizon, false confidence over all frames. "seeds ≥ 0.9" and "seeds below OpenCV"
count the seeds whose set has a visible horizon. Speed: each seed's ratio of median frame
times (OpenCV / ours: bench's `speedup_median`, the target's measure), its lowest and its
median over the seeds; the same for the ratio of mean frame times beside it.
Only the sets scored through `--real` are pooled (the generators' own sets are not seeds).

Exit codes: 0 pooled, 2 a report could not be read (the file and why, on one line).
"""

import argparse
import json
import signal
import statistics
import sys

# The bar for "within 2°" on a degraded class.
TARGET = 0.9


def fail(message):
    print(f"pool_bench: {message}", file=sys.stderr)
    sys.exit(2)


def why(e):
    """An exception in a few words (a decoding error's repr holds the whole file)."""
    text = f"{type(e).__name__}: {e}"
    return text if len(text) <= 160 else text[:157] + "..."


def load(path):
    try:
        with open(path, encoding="utf-8") as f:
            report = json.load(f)
        sets = [a for a in report["accuracy"] if a["generator"] == "real"]
        speed = report.get("speed", [])
    except (OSError, ValueError, KeyError, TypeError) as e:
        fail(f"{path}: not a bench --json report ({why(e)})")
    return sets, speed


def pool(paths):
    rows, speed = {}, {}
    for path in paths:
        sets, seed_speed = load(path)
        try:
            for entry in sets:
                add_set(rows, entry)
            for s in seed_speed:
                # The target's measure is bench's own: OpenCV's median ms over ours (a median is
                # not moved by a frame another process preempted). The ratio of means is kept
                # beside it.
                if s.get("speedup_median") is not None:
                    ratios = speed.setdefault(str(s["size"]), {"median": [], "mean": []})
                    ratios["median"].append(float(s["speedup_median"]))
                    ratios["mean"].append(float(s["speedup_mean"]))
        except (KeyError, TypeError, ValueError, AttributeError, OverflowError) as e:
            fail(f"{path}: a set or speed entry that is not a bench report's ({why(e)})")
    return rows, speed


def add_set(rows, entry):
    """Adds one `--real` set of a report to `rows` (its counts are the shares times frames)."""
    ours = entry["ours"]["accuracy"]
    opencv = (entry.get("opencv") or {}).get("accuracy")
    name, frames, visible = str(entry["set"]), int(ours["frames"]), int(ours["visible"])
    within = {k: float(ours[f"within_{k}deg"] or 0.0) for k in (1, 2, 5)}
    r = rows.setdefault(
        name,
        dict(frames=0, visible=0, within={1: 0, 2: 0, 5: 0}, false=0, usable=0, cv_within=0,
             cv_false=0, cv=opencv is not None, seeds=0, seeds_at_target=0,
             seeds_below_opencv=0),
    )
    r["frames"] += frames
    r["visible"] += visible
    r["false"] += round(float(ours["false_confident_rate"]) * frames)
    # Right and through the estimator's gate, of the frames with a horizon to see.
    r["usable"] += round(float(ours.get("usable") or 0.0) * visible)
    for k, share_ in within.items():
        r["within"][k] += round(share_ * visible)
    r["cv"] = r["cv"] and opencv is not None
    cv_within = float(opencv["within_2deg"] or 0.0) if opencv is not None else 0.0
    if opencv is not None:
        r["cv_within"] += round(cv_within * int(opencv["visible"]))
        r["cv_false"] += round(float(opencv["false_confident_rate"]) * int(opencv["frames"]))
    if visible:
        r["seeds"] += 1
        r["seeds_at_target"] += within[2] >= TARGET - 1e-9
        if opencv is not None:
            r["seeds_below_opencv"] += within[2] < cv_within - 1e-9


def share(count, of):
    return count / of if of else None


def as_json(rows, speed, seeds):
    sets = []
    for name, r in rows.items():
        sets.append({
            "set": name, "frames": r["frames"], "visible": r["visible"],
            "within_1deg": share(r["within"][1], r["visible"]),
            "within_2deg": share(r["within"][2], r["visible"]),
            "within_5deg": share(r["within"][5], r["visible"]),
            "false_confident_rate": share(r["false"], r["frames"]),
            "usable": share(r["usable"], r["visible"]),
            "opencv_within_2deg": share(r["cv_within"], r["visible"]) if r["cv"] else None,
            "opencv_false_confident_rate": share(r["cv_false"], r["frames"]) if r["cv"] else None,
            "seeds_with_visible_horizon": r["seeds"],
            "seeds_at_target": r["seeds_at_target"],
            "seeds_below_opencv": r["seeds_below_opencv"] if r["cv"] else None,
        })
    return {
        "reports": seeds,
        "target_within_2deg": TARGET,
        "sets": sets,
        "speed": [
            {"size": size, "seeds": len(v["median"]),
             # Per seed: OpenCV's median ms over ours (bench's `speedup_median`) ...
             **over_seeds(v["median"], "speedup_lowest", "speedup_median", "seeds_under_2x"),
             # ... and OpenCV's mean ms over ours (bench's `speedup_mean`).
             **over_seeds(v["mean"], "speedup_of_means_lowest", "speedup_of_means_median",
                          "seeds_under_2x_by_means")}
            for size, v in speed.items()
        ],
    }


def over_seeds(ratios, lowest, median, under_2x):
    """The seeds' speed-ups summed up under the given keys: lowest, median, how many under 2×."""
    return {lowest: min(ratios), median: statistics.median(ratios),
            under_2x: sum(x < 2 for x in ratios)}


def as_markdown(pooled):
    f = lambda x: "–" if x is None else f"{x:.2f}"
    lines = [
        f"Pooled over {pooled['reports']} reports. Within 2°: of the frames with a visible "
        "horizon; usable: right and through the estimator's gate, of the same frames; false "
        "confidence: of all frames.",
        "",
        "| set | frames (visible) | within 2° | OpenCV within 2° | usable | false conf "
        f"| OpenCV false conf | seeds ≥ {TARGET} | seeds below OpenCV |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for s in pooled["sets"]:
        below = "–" if s["seeds_below_opencv"] is None else s["seeds_below_opencv"]
        lines.append(
            f"| {s['set']} | {s['frames']} ({s['visible']}) | {f(s['within_2deg'])} "
            f"| {f(s['opencv_within_2deg'])} | {f(s['usable'])} "
            f"| {f(s['false_confident_rate'])} "
            f"| {f(s['opencv_false_confident_rate'])} "
            f"| {s['seeds_at_target']} / {s['seeds_with_visible_horizon']} "
            f"| {below} / {s['seeds_with_visible_horizon']} |")
    for s in pooled["speed"]:
        lines.append("")
        lines.append(
            f"{s['size']}: speed-up over OpenCV per seed (median ms over median ms), lowest "
            f"{s['speedup_lowest']:.2f}×, median {s['speedup_median']:.2f}×; under 2× on "
            f"{s['seeds_under_2x']} of {s['seeds']} seeds. By mean ms: lowest "
            f"{s['speedup_of_means_lowest']:.2f}×, median {s['speedup_of_means_median']:.2f}×, "
            f"under 2× on {s['seeds_under_2x_by_means']}.")
    return "\n".join(lines)


def main():
    # Piped into `head`: stop quietly, as the shell's own tools do.
    signal.signal(signal.SIGPIPE, signal.SIG_DFL)
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("reports", nargs="+", help="bench --json reports, one per seed")
    p.add_argument("--json", action="store_true", help="print JSON instead of Markdown")
    a = p.parse_args()
    rows, speed = pool(a.reports)
    if not rows:
        fail("no --real sets in the reports")
    order = lambda name: (name.rsplit("_", 1)[-1].zfill(5), name)
    rows = dict(sorted(rows.items(), key=lambda kv: order(kv[0])))
    pooled = as_json(rows, speed, len(a.reports))
    print(json.dumps(pooled, indent=1) if a.json else as_markdown(pooled))


if __name__ == "__main__":
    main()
