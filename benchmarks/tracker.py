"""The trackers end to end (JIPDA, PMB, PMBM; scaling, memory); see jointtrack.bench.tracker.

Same as `jointtrack bench tracker`.
"""

import argparse

from jointtrack.bench.tracker import run

if __name__ == "__main__":
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="fewer scans and seeds")
    parser.add_argument("--out", help="also write the results as JSON to this file")
    parser.add_argument("--part", action="append", help="run only this part (repeatable)")
    args = parser.parse_args()
    run(quick=args.quick, out=args.out, parts=args.part)
