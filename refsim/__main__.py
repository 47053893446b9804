"""Write one of :data:`refsim.scenarios.SCENARIOS` as a CSV log with its ground truth (JSON).

    python -m refsim seed_example3_oblique log.csv --truth truth.json [--seed 0]
"""

from __future__ import annotations

import argparse
import json
import math
import os

from .record import write_csv
from .scenarios import SCENARIOS


def _plain(value):
    """JSON-ready: NaN as null, numpy scalars as Python numbers."""
    if isinstance(value, dict):
        return {key: _plain(item) for key, item in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(item) for item in value]
    if hasattr(value, "item"):
        value = value.item()
    return None if isinstance(value, float) and math.isnan(value) else value


def truth_record(name, seed, truth):
    """The ground truth of a scenario as a JSON-ready dict: the scalars, the impacts and the flights."""
    return _plain({"scenario": name, "seed": seed, "generator": "refsim", **truth.summary(),
                   "impacts": truth.impacts.to_dict(orient="records"),
                   "flights": truth.flights.to_dict(orient="records")})


def main(argv=None):
    parser = argparse.ArgumentParser(prog="python -m refsim", description=__doc__.splitlines()[0])
    parser.add_argument("scenario", choices=sorted(SCENARIOS))
    parser.add_argument("log", help="the CSV log to write")
    parser.add_argument("--truth", help="the ground truth (JSON) to write")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args(argv)
    log, truth = SCENARIOS[args.scenario](seed=args.seed)
    # written whole or not at all: to a temporary name, then renamed
    temporary = f"{args.log}.part"
    # micrometres and microseconds: far below the noise of every scenario, and a small file
    write_csv(log, temporary, [f"refsim scenario {args.scenario}, seed {args.seed}"], float_format="%.6f")
    if args.truth:
        with open(f"{args.truth}.part", "w") as handle:
            json.dump(truth_record(args.scenario, args.seed, truth), handle)
        os.replace(f"{args.truth}.part", args.truth)
    os.replace(temporary, args.log)


if __name__ == "__main__":
    main()
