"""Where a large part's PARDISO time goes: every factorization of >= 100k unknowns in ``parameterize`` of drawn parts
(``large_family.draw``, in process, no I/O), by whose matrix it is (the spectral conformal layouts' Q + εB, or the
polish's Hessians) and how it was made: ``analysed`` (a new solver: METIS ordering, symbolic and numerical
factorization), ``reanalysed`` (``Factor.refactor`` of a pattern the analysis does not hold: a re-triangulated
scaffold, analysed anew) or ``numeric`` (a pattern within the analysed one: the numerical factorization only).
Prints one JSON line per part (count and seconds per kind, the run's total) and the sums (BENCHMARKS, "Parts never
seen").

Usage: ``python bench/bench_factorizations.py 1000-1019`` (seeds: ranges or single numbers).
"""

from __future__ import annotations

import argparse
import collections
import json
import time
import traceback

from common import machine, seeds
from large_family import draw

MIN_UNKNOWNS = 100_000


class FactorLog:
    """Wraps ``solvers.Factor``'s constructor and ``refactor`` to record (matrix, kind, seconds) per factorization."""

    def __init__(self):
        import heatparam.solvers as solvers

        self.rows: list[tuple[str, str, float]] = []
        make, refactor = solvers.Factor.__init__, solvers.Factor.refactor
        log = self

        def made(factor, A, *args, **kwargs):
            t0 = time.perf_counter()
            make(factor, A, *args, **kwargs)
            if A.shape[0] >= MIN_UNKNOWNS and kwargs.get("numeric", True):
                log.rows.append((log.whose(), "analysed", time.perf_counter() - t0))

        def refactored(factor, A, *args, **kwargs):
            t0 = time.perf_counter()
            out = refactor(factor, A, *args, **kwargs)
            if A.shape[0] >= MIN_UNKNOWNS:
                if out is not factor:
                    log.rows.pop()  # the new Factor logged itself as analysed
                log.rows.append((log.whose(), "numeric" if out is factor else "reanalysed", time.perf_counter() - t0))
            return out

        solvers.Factor.__init__, solvers.Factor.refactor = made, refactored

    @staticmethod
    def whose() -> str:
        names = {f.name for f in traceback.extract_stack(limit=14)}
        return "conformal" if names & {"_shifted_factor", "_factor"} else "newton"

    def summary(self) -> dict[str, list]:
        agg: dict[str, list] = collections.defaultdict(lambda: [0, 0.0])
        for whose, kind, seconds in self.rows:
            agg[f"{whose} {kind}"][0] += 1
            agg[f"{whose} {kind}"][1] += seconds
        return {k: [c, round(s, 2)] for k, (c, s) in sorted(agg.items())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("seeds", help="e.g. 1000-1019 or 5,6,16")
    args = ap.parse_args()
    log = FactorLog()
    from heatparam import parameterize

    print(machine())
    total = collections.Counter()
    for seed in seeds(args.seeds):
        V, F, _ = draw(seed)
        log.rows.clear()
        t0 = time.perf_counter()
        parameterize(V, F)
        row = {"seed": seed, "faces": len(F), "seconds": round(time.perf_counter() - t0, 1)} | log.summary()
        print(json.dumps(row), flush=True)
        total["seconds"] += row["seconds"]
        for key, (count, seconds) in log.summary().items():
            total[f"{key} n"] += count
            total[f"{key} s"] += seconds
    print(json.dumps({k: round(v, 1) for k, v in sorted(total.items())}))


if __name__ == "__main__":
    main()
