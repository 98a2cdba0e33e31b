"""Tracking quality vs Stone Soup's tutorial JPDA; see jointtrack.bench.quality.

Same as `jointtrack bench quality`."""

import argparse

from jointtrack.bench.quality import run

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="one seed, about half the scans")
    parser.add_argument("--out", help="also write the results as JSON (and a plot) to this file")
    args = parser.parse_args()
    run(quick=args.quick, out=args.out)
