"""``bench.py --before REV``: issue 32's figures for an older tree and this one, side by side.

The older tree is a temporary ``git worktree`` of REV (this repository's history) with a
virtual environment of its own, into which that tree is installed (``pip install -e
TREE[test]``: its own code, its own dependencies, its own ``twin`` command, its FMUs built from
its own sources). ``--before-venv DIR`` keeps that environment in DIR for the next run (made
there if missing; the tree is reinstalled into it each run, a few seconds when its
dependencies are already there); without it the environment is made in a temporary folder and
removed with the worktree at the end.

Every figure is measured for both trees in the same repetition, one tree right after the other
(before then after in even repetitions, after then before in odd ones), so a slow spell of this
shared machine hits both alike; the table gives medians:

1. the default ``twin run`` (the paper's replay with the Monte Carlo its tree ships: the sample
   counts are read from each run's summary.json), whole process, from spawn to exit;
2. the same runs' peak memory, all their processes together (benchmarks/treemem.py);
3. the MIL endurance run (scenarios/mil-endurance.toml, 41.7 h), whole process;
4. the endurance scenario's cost per simulated hour: the slope between the same scenario
   stopped at 10 h (``--stop-time``) and run whole, paired within a repetition;
5. the tester system against libcosimpy, 10 min, set-up + stepping (section (b)): each tree's
   ratio, both run by this script's workers (so the same harness times both) in that tree's
   environment, with that tree's scenario file, FMUs and master, and libcosimpy on that tree's
   FMUs; measured :data:`TESTER_REPS_PER_REP` times per repetition (cheap, and noisy);
6. ``twin heldout`` with 50 testers on 2 workers, whole process (``--heldout-reps``: it is long).

It imports neither numpy nor the twin: every figure is a child process of one tree or the other.
"""

from __future__ import annotations

import contextlib
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from treemem import wait_with_tree_peak

ROOT = Path(__file__).resolve().parents[1]
BENCH = Path(__file__).resolve().parent / "bench.py"

#: the environment variables a tree's runs must not inherit: they would point the older tree at
#: this one's code (PYTHONPATH, the FMU sources) or leave out its bytecode cache
DROPPED_ENV = ("PYTHONPATH", "PYTHONDONTWRITEBYTECODE", "TWIN_FMU_SOURCES")

ENDURANCE = "scenarios/mil-endurance.toml"  # relative to each tree
TESTER = "scenarios/base/tester-system.toml"
ENDURANCE_SHORT = "10 h"  # the short run of the cost per simulated hour
TESTER_DURATION, TESTER_STEP = "10 min", "0.1 s"
HELDOUT_TESTERS, HELDOUT_WORKERS = 50, 2
QUICK_HELDOUT_TESTERS = 2
#: figure 5's repetitions per --reps: a pair of its runs takes a second or two, and libcosimpy's
#: worker threads make its time swing by a factor of two when the machine's other jobs take a core
TESTER_REPS_PER_REP = 3


@dataclass(frozen=True)
class Goal:
    """A figure's goal (issue 32): at most or at least ``limit``."""

    limit: float
    at_least: bool = False

    def met(self, value: float) -> bool:
        return value >= self.limit if self.at_least else value <= self.limit

    def text(self, unit: str) -> str:
        return f"{'>=' if self.at_least else '<='} {self.limit:g}{unit}"


@dataclass(frozen=True)
class Figure:
    key: str
    what: str
    unit: str  # as printed after the number: " s", " MB", "x"
    fmt: str
    goal: Goal


FIGURES = {
    f.key: f
    for f in (
        Figure("1", "default `twin run` (paper replay, its Monte Carlo as shipped), whole process", " s", "{:.2f}", Goal(1.5)),
        Figure("2", "the same, peak memory, all processes", " MB", "{:.0f}", Goal(200)),
        Figure("3", f"MIL endurance 41.7 h (`twin run {ENDURANCE}`), whole process", " s", "{:.2f}", Goal(2.5)),
        Figure("4", f"cost per simulated hour, endurance scenario ({ENDURANCE_SHORT} vs 41.7 h)", " s/h", "{:.4f}", Goal(0.03)),
        Figure("5", f"tester system vs libcosimpy, {TESTER_DURATION}, set-up + stepping (libcosimpy / twin)", "x", "{:.2f}", Goal(20, at_least=True)),
        Figure("6", f"`twin heldout` {HELDOUT_TESTERS} testers x 4 scenarios, {HELDOUT_WORKERS} workers, whole process", " s", "{:.1f}", Goal(45)),
    )
}  # fmt: skip


# ----------------------------------------------------------------------------- the trees


@dataclass
class Tree:
    """A checkout and the environment its ``twin`` is installed in."""

    label: str  # "before" / "after"
    rev: str  # its short commit ("-dirty" when this checkout has changes)
    root: Path
    venv: Path

    @property
    def python(self) -> Path:
        return self.venv / "bin" / "python"

    def command(self, *args: str) -> list[str]:
        exe = self.venv / "bin" / "twin"
        return [str(exe), *args] if exe.exists() else [str(self.python), "-m", "twin", *args]

    def env(self) -> dict[str, str]:
        env = {k: v for k, v in os.environ.items() if k not in DROPPED_ENV}
        env["VIRTUAL_ENV"] = str(self.venv)
        env["PATH"] = f"{self.venv / 'bin'}{os.pathsep}{env.get('PATH', '')}"
        return env

    def check(self) -> None:
        """Refuse to measure a tree whose environment imports another tree's twin."""
        where = subprocess.run(
            [str(self.python), "-c", "import twin; print(twin.__file__)"],
            capture_output=True,
            text=True,
            env=self.env(),
            cwd=str(self.root),
        )
        found = Path(where.stdout.strip() or "?").resolve()
        if where.returncode != 0 or not found.is_relative_to(self.root.resolve()):
            raise SystemExit(f"{self.label}: {self.python} imports twin from {found}, not from {self.root}")


def _git(*args: str, cwd: Path = ROOT) -> str:
    proc = subprocess.run(["git", "-C", str(cwd), *args], capture_output=True, text=True)
    if proc.returncode != 0:
        raise SystemExit(f"git {' '.join(args)}: {proc.stderr.strip()}")
    return proc.stdout.strip()


def this_tree(rev: str) -> Tree:
    return Tree("after", rev, ROOT, Path(sys.prefix))


@dataclass
class BeforeTree:
    """The older tree: a worktree of ``rev`` and its environment, removed by :meth:`close`."""

    rev: str
    venv_dir: Path | None
    scratch: Path = field(init=False)
    tree: Tree = field(init=False)

    def open(self) -> Tree:
        try:
            commit = _git("rev-parse", "--verify", "--quiet", f"{self.rev}^{{commit}}")
        except SystemExit:
            raise SystemExit(f"bench.py: --before {self.rev}: not a commit of {ROOT}") from None
        short = _git("rev-parse", "--short", commit)
        self.scratch = Path(tempfile.mkdtemp(prefix=f"twin-before-{short}-"))
        root = self.scratch / "tree"
        print(f"   before: git worktree of {self.rev} ({short}) in {root}", flush=True)
        _git("worktree", "add", "--detach", str(root), commit)
        venv = self.venv_dir or self.scratch / "venv"
        self.tree = Tree("before", short, root, venv)
        fresh = not (venv / "bin" / "python").exists()
        t0 = time.perf_counter()
        if fresh:
            subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
        # its own dependencies as its pyproject.toml asks (quick when the environment has them);
        # [test]: libcosimpy and psutil, which figure 5 and the memory sampling need
        pip = subprocess.run(
            [str(self.tree.python), "-m", "pip", "install", "-q", "-e", f"{root}[test]"],
            capture_output=True,
            text=True,
            env=self.tree.env(),
        )
        if pip.returncode != 0:
            raise SystemExit(f"pip install -e {root}[test] failed:\n{pip.stderr[-3000:]}")
        print(
            f"   before: {'made' if fresh else 'reused'} the environment {venv} and installed the tree "
            f"into it ({time.perf_counter() - t0:.0f} s)",
            flush=True,
        )
        return self.tree

    def close(self) -> None:
        if not hasattr(self, "scratch"):
            return
        with contextlib.suppress(SystemExit):
            _git("worktree", "remove", "--force", str(self.scratch / "tree"))
        shutil.rmtree(self.scratch, ignore_errors=True)
        with contextlib.suppress(SystemExit):
            _git("worktree", "prune")


# ----------------------------------------------------------------------------- measurements


def run_process(tree: Tree, argv: Sequence[str], log: Path) -> tuple[float, float]:
    """``argv`` in ``tree``'s environment and folder: (wall s from spawn to exit, peak MB of its
    process tree). Raises with the end of its output when it fails."""
    with log.open("wb") as out:
        t0 = time.perf_counter()
        proc = subprocess.Popen(
            list(argv), stdout=out, stderr=subprocess.STDOUT, cwd=str(tree.root), env=tree.env()
        )
        status, _, peak_mb = wait_with_tree_peak(proc.pid)
        wall = time.perf_counter() - t0
    code = os.waitstatus_to_exitcode(status)
    if code != 0:
        tail = log.read_text(errors="replace")[-2000:]
        raise RuntimeError(f"{tree.label}: {' '.join(argv)} exited {code}:\n{tail}")
    return wall, peak_mb


def sample_counts(summary: dict[str, Any]) -> str:
    """The Monte Carlo's sample counts a run's summary.json reports, e.g. "200 prior + 200 updated"."""
    drift = summary.get("drift_mm") or {}
    parts = [
        f"{drift[key]['samples']} {key}"
        for key in ("prior", "updated")
        if isinstance(drift.get(key), dict) and drift[key].get("samples")
    ]
    if not parts and drift.get("samples"):
        parts.append(f"{drift['samples']} samples")
    failed = (
        (drift.get("uncertainty") or {}).get("failed") if isinstance(drift.get("uncertainty"), dict) else None
    )
    if failed:
        parts.append(f"{failed} failed")
    return " + ".join(parts) or "no Monte Carlo"


def measure_default(tree: Tree, out: Path) -> dict[str, Any]:
    wall, peak = run_process(tree, tree.command("run", "--quiet", "--out", str(out)), out.with_suffix(".log"))
    summary = json.loads((out / "summary.json").read_text())
    return {"wall_s": wall, "peak_mb": peak, "samples": sample_counts(summary)}


def measure_endurance(tree: Tree, out: Path, stop: str | None) -> dict[str, Any]:
    args = ["run", str(tree.root / ENDURANCE), "--quiet", "--out", str(out)]
    if stop:
        args += ["--stop-time", stop]
    wall, peak = run_process(tree, tree.command(*args), out.with_suffix(".log"))
    summary = json.loads((out / "summary.json").read_text())
    return {"wall_s": wall, "peak_mb": peak, "sim_h": summary["sim_end_s"] / 3600}


def measure_heldout(tree: Tree, out: Path, testers: int) -> dict[str, Any]:
    args = [
        "heldout",
        "--testers",
        str(testers),
        "--workers",
        str(HELDOUT_WORKERS),
        "--quiet",
        "--out",
        str(out),
    ]
    wall, peak = run_process(tree, tree.command(*args), out.with_suffix(".log"))
    return {"wall_s": wall, "peak_mb": peak}


def worker(tree: Tree, flag: str, spec: dict[str, Any]) -> dict[str, Any]:
    """bench.py's ``--twin-worker``/``--libcosim-worker`` run by ``tree``'s Python (so with its
    twin, its FMUs, its libcosimpy), in a temporary folder of its own as section (b)'s are."""
    with tempfile.TemporaryDirectory(prefix="twin-bench-worker-") as tmp:
        env = {**tree.env(), "TMPDIR": tmp}
        proc = subprocess.run(
            [str(tree.python), str(BENCH), flag],
            input=json.dumps(spec),
            capture_output=True,
            text=True,
            env=env,
            cwd=str(tree.root),
        )
    if proc.returncode != 0:
        lines = [ln.strip() for ln in proc.stderr.splitlines() if ln.strip()]
        what = [ln for ln in lines if ln.startswith("what():")]
        raise RuntimeError(
            f"{tree.label} {flag}: " + "\n".join((what or lines or [str(proc.returncode)])[-5:])
        )
    return json.loads(proc.stdout.strip().splitlines()[-1])


class Tester:
    """Figure 5 for one tree: its master (default loop) and libcosimpy, each a fresh process."""

    def __init__(self, tree: Tree) -> None:
        self.tree = tree
        self.spec: dict[str, Any] = {
            "duration": TESTER_DURATION,
            "step": TESTER_STEP,
            "tester": str(tree.root / TESTER),
            "loop": None,
        }
        first = worker(tree, "--twin-worker", self.spec)  # warm-up; its first row: the initialized outputs
        self.spec["init_outputs"] = first["first"]
        # as section (b): libcosim gets the system as connected if it can initialize it, else
        # with the connections it cannot initialize replaced by the sources' initial values
        self.mode = "connect"
        try:
            worker(tree, "--libcosim-worker", {**self.spec, "mode": "connect"})
        except RuntimeError:
            self.mode = "initial"

    def measure(self) -> dict[str, Any]:
        ours = worker(self.tree, "--twin-worker", self.spec)
        lib = worker(self.tree, "--libcosim-worker", {**self.spec, "mode": self.mode})
        return {
            "ratio": lib["total_s"] / ours["total_s"],
            "ratio_loop": lib["loop_s"] / ours["loop_s"] if ours.get("loop_s") else float("nan"),
            "ours_s": ours["total_s"],
            "lib_s": lib["total_s"],
        }


# ----------------------------------------------------------------------------- the table


def median(xs: Sequence[float]) -> float:
    return float(statistics.median(xs))


def ratio_text(before: float | None, after: float | None) -> str:
    if before is None or after is None or before == 0:
        return ""
    return f"{after / before:.2f}"


def comparison_table(
    rows: Sequence[tuple[Figure, float | None, float | None, str, str]], before: str, after: str, quick: bool
) -> str:
    """The Markdown table: figure | before | after | after/before | goal | met.

    ``rows``: (figure, before's median, after's median, a note for the before cell, one for the
    after cell); a missing median prints "failed". With ``quick`` the goal is not judged for
    the figures measured on a smaller problem (the held-out validation's fewer testers).
    """
    lines = [
        f"| figure | before ({before}) | after ({after}) | after/before | goal | met |",
        "|---|---:|---:|---:|---:|---|",
    ]
    for fig, b, a, note_b, note_a in rows:

        def cell(v: float | None, note: str, fig: Figure = fig) -> str:
            if v is None:
                return "failed"
            text = fig.fmt.format(v) + fig.unit
            return f"{text} ({note})" if note else text

        judged = a is not None and not (quick and fig.key == "6")
        met = ("yes" if fig.goal.met(a) else "**no**") if judged and a is not None else ""
        lines.append(
            f"| {fig.key}. {fig.what} | {cell(b, note_b)} | {cell(a, note_a)} | {ratio_text(b, a)} "
            f"| {fig.goal.text(fig.unit)} | {met} |"
        )
    return "\n".join(lines)


# ----------------------------------------------------------------------------- the run


@dataclass
class Plan:
    figures: str  # e.g. "123456"
    reps: int
    heldout_reps: int
    quick: bool
    load: tuple[float, float] = (0.0, 0.0)  # the machine's load average at the start and the end

    @property
    def heldout_testers(self) -> int:
        return QUICK_HELDOUT_TESTERS if self.quick else HELDOUT_TESTERS


class Measurements:
    """Every measurement the figures need, per tree: ``got[label][quantity]``, one value a repetition.

    Each step measures one tree once and returns its line of progress; a step that fails for
    a tree is not tried again for it, and the other figures go on.
    """

    def __init__(self, plan: Plan, trees: Sequence[Tree], scratch: Path) -> None:
        self.plan, self.trees, self.scratch = plan, list(trees), scratch
        self.got: dict[str, dict[str, list[Any]]] = {t.label: {} for t in trees}
        self.failures: dict[str, str] = {}
        self.testers: dict[str, Tester] = {}

    def keep(self, tree: Tree, key: str, value: Any) -> None:
        self.got[tree.label].setdefault(key, []).append(value)

    def warm_up(self) -> None:
        print("\n== warm-up (each tree: FMUs and stepper built or found in the cache, bytecode compiled)")
        for tree in self.trees:
            tree.check()
            out = self.scratch / f"warm-{tree.label}"
            argv = tree.command("run", "--uncertainty", "0", "--quiet", "--out", str(out))
            wall, _ = run_process(tree, argv, out.with_suffix(".log"))
            print(f"   {tree.label:6s} twin run --uncertainty 0: {wall:.2f} s", flush=True)

    def default(self, tree: Tree, rep: int) -> str:
        r = measure_default(tree, self.scratch / f"default-{tree.label}-{rep}")
        self.keep(tree, "default_s", r["wall_s"])
        self.keep(tree, "default_mb", r["peak_mb"])
        self.keep(tree, "samples", r["samples"])
        return f"{r['wall_s']:.2f} s, {r['peak_mb']:.0f} MB ({r['samples']})"

    def endurance(self, tree: Tree, rep: int) -> str:
        text = []
        short = None
        if "4" in self.plan.figures:  # the short run right before the long one: a pair
            short = measure_endurance(tree, self.scratch / f"short-{tree.label}-{rep}", ENDURANCE_SHORT)
            self.keep(tree, "short_s", short["wall_s"])
            self.keep(tree, "short_h", short["sim_h"])
            text.append(f"{short['sim_h']:.1f} h: {short['wall_s']:.2f} s")
        long = measure_endurance(tree, self.scratch / f"long-{tree.label}-{rep}", None)
        self.keep(tree, "long_s", long["wall_s"])
        text.append(f"{long['sim_h']:.1f} h: {long['wall_s']:.2f} s, {long['peak_mb']:.0f} MB")
        if short is not None:
            slope = (long["wall_s"] - short["wall_s"]) / (long["sim_h"] - short["sim_h"])
            self.keep(tree, "per_h", slope)
            text.append(f"{slope:.4f} s/h")
        return "; ".join(text)

    def tester(self, tree: Tree, rep: int) -> str:
        if tree.label not in self.testers:
            self.testers[tree.label] = Tester(tree)
        r = self.testers[tree.label].measure()
        self.keep(tree, "tester_ratio", r["ratio"])
        self.keep(tree, "tester_ratio_loop", r["ratio_loop"])
        return (
            f"twin {r['ours_s']:.3f} s, libcosimpy {r['lib_s']:.3f} s ({self.testers[tree.label].mode}): "
            f"{r['ratio']:.2f}x ({r['ratio_loop']:.2f}x stepping only)"
        )

    def heldout(self, tree: Tree, rep: int) -> str:
        testers = self.plan.heldout_testers
        r = measure_heldout(tree, self.scratch / f"heldout-{tree.label}-{rep}", testers)
        self.keep(tree, "heldout_s", r["wall_s"])
        return f"{r['wall_s']:.1f} s, {r['peak_mb']:.0f} MB ({testers} testers)"

    def one(self, name: str, step: Callable[[Tree, int], str], tree: Tree, rep: int) -> str:
        if f"{tree.label}: {name}" in self.failures:
            return "skipped (failed before)"
        try:
            return step(tree, rep)
        except Exception as exc:  # one figure failing leaves the others
            self.failures[f"{tree.label}: {name}"] = str(exc)
            return f"FAILED: {exc}"

    def run(self) -> dict[str, dict[str, list[Any]]]:
        """The steps the plan's figures need, both trees in every repetition, the order of the
        two flipped every other repetition."""
        self.warm_up()
        steps = [
            ("12", "default twin run", self.default, self.plan.reps),
            ("34", "MIL endurance", self.endurance, self.plan.reps),
            ("5", "tester vs libcosimpy", self.tester, self.plan.reps * TESTER_REPS_PER_REP),
            ("6", "twin heldout", self.heldout, self.plan.heldout_reps),
        ]
        for figures, name, step, reps in steps:
            if not set(figures) & set(self.plan.figures):
                continue
            print(f"\n== {name} ({reps} repetitions, both trees in each)", flush=True)
            for rep in range(reps):
                for tree in self.trees if rep % 2 == 0 else self.trees[::-1]:
                    line = self.one(name, step, tree, rep)
                    print(f"   rep {rep + 1}/{reps} {tree.label:6s} {line}", flush=True)
        for what, why in self.failures.items():
            print(f"   FAILED {what}: {why}")
        return self.got


def rows_of(plan: Plan, got: dict[str, dict[str, list[Any]]]) -> list[tuple[Figure, Any, Any, str, str]]:
    def med(label: str, key: str) -> float | None:
        xs = got[label].get(key)
        return median(xs) if xs else None

    def notes(key: str) -> tuple[str, str]:
        return tuple(  # type: ignore[return-value]
            ", ".join(sorted(set(got[label].get(key, [])))) for label in ("before", "after")
        )

    table: dict[str, tuple[str, str]] = {
        "1": ("default_s", "samples"),
        "2": ("default_mb", ""),
        "3": ("long_s", ""),
        "4": ("per_h", ""),
        "5": ("tester_ratio", ""),
        "6": ("heldout_s", ""),
    }
    rows = []
    for key in plan.figures:
        quantity, note_key = table[key]
        cells = []
        for label, note in zip(("before", "after"), notes(note_key) if note_key else ("", ""), strict=True):
            extra = f"n={len(got[label].get(quantity, []))}"
            if key == "6" and plan.quick:
                extra += f", {plan.heldout_testers} testers"
            cells.append(", ".join(x for x in (note, extra) if x))
        rows.append((FIGURES[key], med("before", quantity), med("after", quantity), *cells))
    return rows


def footnotes(plan: Plan, got: dict[str, dict[str, list[Any]]]) -> str:
    """What the table's figures are, in a few lines under it."""
    lines = [
        "",
        "Medians of the repetitions (n); both trees measured in each repetition, one right after the other "
        "(the order flipped every other repetition). after/before < 1: the after tree is faster "
        "(figure 5: > 1, libcosimpy's time over the twin's grows). Load average (1 min) at the start "
        f"and the end: {plan.load[0]:.1f}, {plan.load[1]:.1f} on {os.cpu_count()} cores (the machine's "
        "other jobs make every figure slower and noisier).",
    ]
    if "2" in plan.figures:
        lines.append(
            "- figure 2: the largest sum of the resident memory of the run's processes (the run, its plot helper, "
            "the Monte Carlo's Dask workers), sampled every 20 ms (benchmarks/treemem.py); a page two processes "
            "share counts in each."
        )
    if "4" in plan.figures:
        for label in ("before", "after"):
            short, long = got[label].get("short_s"), got[label].get("long_s")
            per_h = got[label].get("per_h")
            if short and long and per_h:
                fixed = median(short) - median(per_h) * median(got[label]["short_h"])
                lines.append(
                    f"- figure 4, {label}: {ENDURANCE_SHORT} {median(short):.2f} s, 41.7 h {median(long):.2f} s; "
                    f"median of the paired slopes {median(per_h):.4f} s per simulated hour on top of about "
                    f"{fixed:.2f} s fixed"
                )
    if "5" in plan.figures:
        for label in ("before", "after"):
            if got[label].get("tester_ratio_loop"):
                lines.append(
                    f"- figure 5, {label}: {median(got[label]['tester_ratio_loop']):.2f}x stepping only "
                    "(all five FMUs at 0.1 s, the default master loop, each side a fresh process timed inside it)"
                )
    return "\n".join(lines)


def compare(
    rev: str,
    venv: Path | None,
    plan: Plan,
    after_rev: str,
    machine_line: str,
) -> tuple[str, bool]:
    """Measure, print and return (the table with its notes, whether every figure was measured)."""
    before = BeforeTree(rev, venv)
    try:
        trees = [before.open(), this_tree(after_rev)]
        for t in trees:
            print(f"   {t.label:6s} {t.rev}: {t.root} ({t.python})")
        with tempfile.TemporaryDirectory(prefix="twin-bench-before-") as tmp:
            t0, load = time.perf_counter(), os.getloadavg()[0]
            got = Measurements(plan, trees, Path(tmp)).run()
            plan.load = (load, os.getloadavg()[0])
            print(f"\n(measuring took {time.perf_counter() - t0:.0f} s)")
    finally:
        before.close()
    rows = rows_of(plan, got)
    table = comparison_table(rows, trees[0].rev, trees[1].rev, plan.quick) + "\n" + footnotes(plan, got)
    print(
        f"\n== before ({trees[0].rev}) and after ({trees[1].rev}), issue 32's figures\n\nmachine: {machine_line}\n\n{table}"
    )
    complete = all(b is not None and a is not None for _, b, a, _, _ in rows)
    return table, complete
