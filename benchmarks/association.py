"""Association benchmark: jointtrack vs Stone Soup 1.9.1 and pyehm on DESIGN.md's clusters.

Same as ``jointtrack bench association``; see :mod:`jointtrack.bench.association`.

    python benchmarks/association.py [--quick] [--out results.json]
"""

from __future__ import annotations

import argparse

from jointtrack.bench.association import run


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="peers on fewer sizes; < 1 minute")
    parser.add_argument("--out", default=None, help="also write the results as JSON here")
    args = parser.parse_args()
    run(quick=args.quick, out=args.out)


if __name__ == "__main__":
    main()
