"""A labelled frame set directory (frame_NNNNNN.png, camera.toml, truth.csv), as the bench's
`--real` reads it: what the scripts that pass one set into another (camera_chain.py,
h264_link.py) share."""

import os
import shutil
import sys

LABELS = ("camera.toml", "truth.csv")


def fail(message):
    """The running script's one-line refusal, exit status 1."""
    print(f"{os.path.basename(sys.argv[0])}: {message}", file=sys.stderr)
    sys.exit(1)


def frame_names(directory):
    """The set's frame file names in order; refuses a directory that is not a set."""
    for name in LABELS:
        if not os.path.isfile(os.path.join(directory, name)):
            fail(f"{os.path.join(directory, name)}: missing (not a set directory)")
    names = sorted(n for n in os.listdir(directory) if n.startswith("frame_") and n.endswith(".png"))
    if not names:
        fail(f"{directory}: no frame_NNNNNN.png frames")
    return names


def copy_labels(source, output):
    """Creates `output` with the same camera and truth as `source` (a link moves no horizon)."""
    os.makedirs(output, exist_ok=True)
    for name in LABELS:
        shutil.copy(os.path.join(source, name), os.path.join(output, name))
