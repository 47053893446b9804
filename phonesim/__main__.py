"""``python -m phonesim <preset> out.mp4 [--seed N] [--downscale F]``: render a preset clip and its truth."""

from __future__ import annotations

import argparse
import time

from .presets import PRESET_SUFFIX, PRESETS
from .render import render_clip, truth_paths


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(prog="python -m phonesim", description=__doc__)
    parser.add_argument("preset", choices=sorted(PRESETS))
    parser.add_argument("output", help="clip path; the suffix picks the container (.mp4, .mov, .mkv, .avi)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--downscale", type=float, default=1.0, help="pixel size factor (0.25: a quarter size)")
    args = parser.parse_args(argv)
    config = PRESETS[args.preset].scaled(args.downscale)
    start = time.perf_counter()
    truth = render_clip(config, args.output, seed=args.seed)
    elapsed = time.perf_counter() - start
    clip = truth.summary["clip"]
    print(f"{args.output}: {clip['frame_count']} frames {clip['width_px']}x{clip['height_px']} displayed, "
          f"rotation {clip['rotation_deg']}, {len(truth.impacts)} impacts, {elapsed:.1f} s "
          f"(the preset was described as {PRESET_SUFFIX[args.preset]}); truth: "
          + ", ".join(str(p) for p in truth_paths(args.output)))


if __name__ == "__main__":
    main()
