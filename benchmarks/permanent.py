"""Permanent benchmark: jointtrack vs thewalrus on DESIGN.md's canonical workloads.

Same as ``jointtrack bench permanent``; see :mod:`jointtrack.bench.permanent`.

    python benchmarks/permanent.py [--quick] [--out results.json]
"""

from __future__ import annotations

import argparse

from jointtrack.bench.permanent import run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes; about a minute")
    parser.add_argument("--out", default=None, help="also write the results as JSON here")
    args = parser.parse_args()
    run(quick=args.quick, out=args.out)


if __name__ == "__main__":
    main()
