"""The long fuzz run: 10 000 mutated scenes through load and a short simulate, with a table of what happened.

Run with ``bash scripts/dev.sh fuzz`` (or ``.venv/bin/python benchmarks/fuzz.py --examples 10000``). Unlike the CI
test (``tests/scene/test_fuzz.py``), it does not stop at the first broken promise: it counts every outcome, lists each
traceback and each run over its time budget with the mutant's text, and exits 1 if there was any.
"""

from __future__ import annotations

import argparse
import sys
import time
import traceback
from pathlib import Path

from hypothesis import HealthCheck, given, settings

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from support.fuzzing import Tally, check, mutants  # noqa: E402


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--examples", type=int, default=10_000, help="mutants to try (default 10 000)")
    parser.add_argument("--seed", type=int, default=0, help="Hypothesis seed (default 0)")
    options = parser.parse_args()
    tally = Tally()
    start = time.perf_counter()

    @settings(max_examples=options.examples, deadline=None, database=None, phases=["generate"],
              suppress_health_check=list(HealthCheck))
    @given(mutants())
    def run(mutant: tuple[str, str]) -> None:
        base, text = mutant
        try:
            check(base, text, tally)
        except AssertionError as error:
            tally.outcomes["BROKEN PROMISE"] += 1
            tally.failures.append(str(error))
        except Exception:  # a traceback: the defect this run exists to find
            tally.outcomes["TRACEBACK"] += 1
            tally.failures.append(f"{base}:\n{traceback.format_exc()}\n{text}")
        done = sum(tally.outcomes.values())
        if done % 500 == 0:
            print(f"  {done} mutants, {time.perf_counter() - start:.0f} s", file=sys.stderr, flush=True)

    seeded = run if options.seed is None else __import__("hypothesis").seed(options.seed)(run)
    seeded()
    total = sum(tally.outcomes.values())
    print(f"\n{'outcome':<40} {'mutants':>8}")
    for outcome, count in sorted(tally.outcomes.items(), key=lambda item: -item[1]):
        print(f"{outcome:<40} {count:>8}")
    print(f"{'total':<40} {total:>8}")
    print(f"\nwall time {time.perf_counter() - start:.0f} s; slowest simulation {tally.slowest[0]:.2f} s "
          f"({tally.slowest[1]})")
    for failure in tally.failures[:20]:
        print("\n" + "-" * 100 + "\n" + failure)
    return 1 if tally.failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
