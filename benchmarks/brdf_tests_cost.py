"""CPU cost of the BRDF property tests' sampling checks, per model:
`python benchmarks/brdf_tests_cost.py [chi2] [albedo] [furnace]` (prints numbers, asserts nothing).

Runs, in this one process, tests/test_brdf_properties.py's chi-square cases (``CHI2_CASES``: every
non-delta model's parameter sets at four angles, BRDF_CHI2_SAMPLES samples each), its directional
albedo test and its furnace test, and prints the process CPU seconds each took per model (largest
first) and in all. The first model measured also pays the imports (scipy's on the first p-value)
and a measured table's one-time tabulation. CPU seconds rather than wall time: the figure does not
move with other processes on a shared machine as much (run it twice anyway).
"""

from __future__ import annotations

import collections
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))
import test_brdf_properties as props  # noqa: E402

KINDS = {
    "chi2": lambda: [(c[0], lambda c=c: props.test_chi2_sample_matches_pdf(*c)) for c in props.CHI2_CASES],
    "albedo": lambda: [(n, lambda n=n: props.test_albedo_at_most_one(n)) for n in props.NAMES],
    "furnace": lambda: [(n, lambda n=n: props.test_furnace_two_estimators_agree(n)) for n in props.NON_DELTA],
}


def main(argv) -> None:
    for kind in argv or list(KINDS):
        if kind not in KINDS:
            raise SystemExit(f"unknown check {kind!r}; allowed: {', '.join(KINDS)}")
        per_model = collections.Counter()
        for name, run in KINDS[kind]():
            t0 = time.process_time()
            run()
            per_model[name] += time.process_time() - t0
        models = "  ".join(f"{n} {s:.2f}" for n, s in per_model.most_common())
        print(f"{kind}: {sum(per_model.values()):.1f} CPU s  ({models})", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
