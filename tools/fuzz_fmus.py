"""Long fuzz runs of the FMUs under AddressSanitizer and UBSan (issue 13).

The CI test (tests/fmus/test_fuzz_sanitized.py) runs the harness tests/fmus/fuzz/fuzz_fmu.c for a
few seconds per model with one fixed seed; this script runs the same harness with many seeds and
as many iterations as wanted, in parallel, until a time budget is spent or a run fails::

    python tools/fuzz_fmus.py                                  # every model, 10 min, all cores
    python tools/fuzz_fmus.py --models HydraulicLoader --iterations 1000000 --minutes 60
    python tools/fuzz_fmus.py --seeds 100-120 --jobs 1         # exactly these seeds

Every run is reproducible from its seed: a failure prints the command that replays it (add -v to
that command to see every message of the FMU). The harness drives itself (its own deterministic
generator, mutations and oracles), so it needs gcc only; no libFuzzer (clang) is used.

Needs the twin importable (PYTHONPATH=src or an installed checkout) and a compiler with the
sanitizer runtimes (Debian: apt-get install -y gcc). Exit code 0 if every run was clean, 1 if one
failed, 2 for bad arguments or no sanitizer runtime.
"""

from __future__ import annotations

import argparse
import itertools
import os
import sys
import tempfile
import time
from collections.abc import Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ThreadPoolExecutor, wait
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(REPO))

from tests.fmus.sanitized import FuzzResult, build_harness, run_harness, sanitizer_problem  # noqa: E402
from twin.fmu.build import model_names  # noqa: E402


def parse_seeds(text: str) -> Iterator[int]:
    """``"7"`` -> 7; ``"100-120"`` -> 100..120; ``"1000-"`` -> 1000, 1001, ... without end."""
    first, dash, last = text.partition("-")
    if not dash:
        return iter([int(first)])
    return iter(range(int(first), int(last) + 1)) if last else itertools.count(int(first))


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--models", default=",".join(model_names()), help="comma-separated (default: every model)")
    p.add_argument("--iterations", type=int, default=200_000, help="per run (default 200000)")
    p.add_argument("--seeds", default="1000-", help="N, A-B or A- (default 1000-: until the time is up)")
    p.add_argument("--minutes", type=float, default=10.0, help="time budget (default 10)")
    p.add_argument("--jobs", type=int, default=os.cpu_count() or 1, help="parallel runs (default: all cores)")
    p.add_argument("--build-dir", type=Path, default=None, help="keep the harness binaries here")
    p.add_argument("--random-only", action="store_true", help="skip the crafted cases")
    return p.parse_args(argv)


def report(model: str, seed: int, exe: Path, iterations: int, result: FuzzResult) -> bool:
    """Print one line for a run (the harness's counts, or the failure and how to replay it)."""
    if result.clean:
        print(f"ok    {model} seed {seed}: {result.stdout.strip().partition(':')[2].strip()}", flush=True)
        return True
    print(
        f"FAIL  {model} seed {seed} (exit {result.returncode}): replay with\n  {exe} {seed} {iterations} -v"
    )
    print(result.tail(60), flush=True)
    return False


def fuzz(args: argparse.Namespace, harnesses: dict[str, Path]) -> bool:
    """Run seeds round the models until the budget is spent, the seeds run out or a run fails."""
    deadline = time.monotonic() + 60.0 * args.minutes
    jobs = ((model, seed) for seed in parse_seeds(args.seeds) for model in harnesses)
    pending: dict[Future[FuzzResult], tuple[str, int]] = {}
    ok = True
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        while ok:
            while len(pending) < args.jobs and time.monotonic() < deadline:
                job = next(jobs, None)
                if job is None:
                    break
                run = pool.submit(
                    run_harness, harnesses[job[0]], job[1], args.iterations, random_only=args.random_only
                )
                pending[run] = job
            if not pending:
                break
            done, _ = wait(pending, return_when=FIRST_COMPLETED)
            for future in done:
                model, seed = pending.pop(future)
                ok = report(model, seed, harnesses[model], args.iterations, future.result()) and ok
    return ok


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    problem = sanitizer_problem()
    if problem:
        print(f"cannot fuzz: {problem}", file=sys.stderr)
        return 2
    models = [m for m in args.models.split(",") if m]
    unknown = sorted(set(models) - set(model_names()))
    if unknown:
        print(f"unknown models: {', '.join(unknown)} (known: {', '.join(model_names())})", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="twin-fuzz-") as tmp:
        out = args.build_dir or Path(tmp)
        harnesses = {m: build_harness(m, out) for m in models}
        return 0 if fuzz(args, harnesses) else 1


if __name__ == "__main__":
    sys.exit(main())
