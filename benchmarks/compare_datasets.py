"""Compare two dataset directories shard by shard (not a test): every .npz member np.array_equal,
and whether the shard files are byte-identical.

    python benchmarks/compare_datasets.py DIR_BEFORE DIR_AFTER

Used to check that a speed-up leaves the maps bit-identical: build the same config with
PYTHONPATH=/work/main (before) and with the branch (after), then compare.
"""
import sys
from pathlib import Path

import numpy as np


def main() -> None:
    a, b = Path(sys.argv[1]), Path(sys.argv[2])
    fa, fb = sorted((a / "shards").glob("*.npz")), sorted((b / "shards").glob("*.npz"))
    if [f.name for f in fa] != [f.name for f in fb]:
        sys.exit("shard names differ")
    same_bytes = 0
    for x, y in zip(fa, fb):
        za, zb = np.load(x), np.load(y)
        if za.files != zb.files:
            sys.exit(f"{x.name}: members differ")
        for k in za.files:
            if not np.array_equal(za[k], zb[k]):
                sys.exit(f"{x.name}: member {k} differs")
        same_bytes += x.read_bytes() == y.read_bytes()
    print(f"{len(fa)} shards: every member array equal; {same_bytes}/{len(fa)} shard files byte-identical")


if __name__ == "__main__":
    main()
