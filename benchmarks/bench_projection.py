"""Speed benchmark of the projection engine (the runnable script form of ``jaxproj bench``).

Per-projection time and throughput of the relaxed and full objectives (compilation timed apart,
answers checked against a NumPy + cKDTree reference of the paper's algorithm, which is also the
speed baseline), kernel-bank build time, single-frame streaming latency and MJX rollout steps/s.
See ``jaxproj/bench.py`` for what each number means and ``benchmarks/RESULTS.md`` for results.

    python benchmarks/bench_projection.py [--quick] [--device cpu|gpu] [--json OUT]
"""

from __future__ import annotations

import argparse
import sys

from jaxproj import bench
from jaxproj.exceptions import JaxprojError


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    bench.add_arguments(ap)
    args = ap.parse_args(argv)
    try:
        return bench.main(args)
    except JaxprojError as e:
        print(f"bench_projection: error: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
