"""The first Ctrl-C (SIGINT) or SIGTERM ends the command, whatever it is doing, within a few
seconds: one line on stderr, exit code 130 or 143, every process it started gone.

In a process of its own (the console script, ``python -m twin``: :func:`install`):

* The signals are received by a watcher thread only. The main thread and every thread and
  process started after :func:`install` (Dask's scheduler loop, nannies and workers, the plot
  helper, cmake, make and the compilers) have SIGINT and SIGTERM blocked: a terminal's Ctrl-C
  reaches the whole process group, and a worker that died of it printed tracebacks and made
  its nanny restart it ("Nanny failed to start") while the command tried to stop. This
  process ends them itself. Nor does the main thread ever see a KeyboardInterrupt: raised in
  a library's callback it was the tracebacks and hangs of the command's own shutdown.
* A command marks the stretches that stop cleanly on :func:`caught` (``controls.stop``: a
  run with its Monte Carlo, a sweep, a held-out validation) as :func:`cooperative`: a signal
  there gives the main thread :data:`GRACE_S` to write what it recorded (the summary saying
  "interrupted") and end. Anywhere else (the imports, ``twin build``, the FMUs' first-use
  build, ``twin identify``), once the grace has run out (a Dask cluster still starting), or
  when the stretch ends, the watcher ends the command itself: it runs what the command registered with :func:`on_hard_exit` (a run
  marks its summary.json "interrupted"), kills every process the command started, says the
  one line and leaves without the interpreter's teardown (which waits for Dask's threads).
* A second signal changes nothing: the first one's ending is under way.

Called as a function (:func:`twin.cli.main` from a program or a test), the command only
answers :func:`caught` (the caller's process is not the command's to tune).
"""

from __future__ import annotations

import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager, suppress
from typing import Any

__all__ = [
    "EXIT_ON_SIGNAL",
    "GRACE_S",
    "caught",
    "cooperative",
    "end_children",
    "exit_code",
    "install",
    "installed",
    "on_hard_exit",
    "park",
    "record",
    "say",
]

#: a command stopped by a signal ends with the shell's code for it
EXIT_ON_SIGNAL = {"SIGINT": 130, "SIGTERM": 143}
#: seconds a cooperative stretch has, after the first signal, to write its outputs and end
GRACE_S = 2.5
_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class _State:
    def __init__(self) -> None:
        self.lock = threading.RLock()
        self.name: str | None = None
        self.said = False
        self.ending = False
        self.ender: int | None = None  # the thread that ends the command
        self.depth = 0  # nesting of cooperative stretches
        self.hooks: list[Callable[[str], str | None]] = []
        self.where: str | None = None
        self.installed = False


_state = _State()


def reset() -> None:
    """Forget an earlier command's signal (a program that calls :func:`twin.cli.main` twice)."""
    global _state
    if not _state.installed:
        _state = _State()


def caught() -> str | None:
    """The name of the first signal that came ("SIGINT", "SIGTERM"), or None."""
    return _state.name


def exit_code(name: str | None = None) -> int:
    """The exit code for the signal ``name`` (default: the one that came)."""
    return EXIT_ON_SIGNAL.get(name or _state.name or "", 130)


def say(line: str | None = None) -> bool:
    """Print the command's one line about the interruption (``line``, or a plain one), unless
    it has been printed already; True when this call printed it."""
    park()
    with _state.lock:
        if _state.said:
            return False
        _state.said = True
    if line is None:
        line = _line()
    with suppress(OSError, ValueError):
        print(line, file=sys.stderr, flush=True)
    return True


def park() -> None:
    """Wait here for the end when another thread is ending the command: what this one would
    print goes nowhere now, and its own exit must not come first."""
    if _state.ending and _state.ender != threading.get_ident():
        threading.Event().wait()


def on_hard_exit(hook: Callable[[str], str | None], where: str | None = None) -> None:
    """Run ``hook(signal name)`` if the watcher has to end the command itself (it must be
    quick); what it returns, if anything, is the one line. ``where`` names the output folder
    for the plain line."""
    with _state.lock:
        _state.hooks.append(hook)
        if where is not None:
            _state.where = where


def installed() -> bool:
    """Whether the watcher receives the signals (:func:`install`)."""
    return _state.installed


def record(signum: int) -> bool:
    """Note a signal; True for the first one."""
    with _state.lock:
        if _state.name is not None:
            return False
        _state.name = signal.Signals(signum).name
        return True


@contextmanager
def cooperative() -> Iterator[None]:
    """A stretch that ends by itself soon after :func:`caught` answers: a signal within gives
    it :data:`GRACE_S` (not an immediate end)."""
    with _state.lock:
        _state.depth += 1
    try:
        yield
    finally:
        with _state.lock:
            _state.depth -= 1
            late = _state.installed and _state.name is not None and _state.depth == 0
        if late:  # still running after the stretch: nothing more stops by itself
            _hard_exit()


def install() -> None:
    """Receive SIGINT and SIGTERM on a watcher thread (see the module); call from the main
    thread of a process that is the command's alone, before anything starts a thread."""
    if _state.installed:
        return
    # blocked first: from here a signal waits, pending, for the watcher, which alone unblocks
    # them. Blocked last, one that came while the main thread waited for the watcher to start
    # (milliseconds on a busy machine) met the default handler: a KeyboardInterrupt in the main
    # thread racing the watcher's end of the command, a cut traceback and exit code 1.
    # Every thread and process this one starts from here inherits the block
    signal.pthread_sigmask(signal.SIG_BLOCK, _SIGNALS)
    read, write = os.pipe()
    os.set_blocking(write, False)
    signal.set_wakeup_fd(write, warn_on_full_buffer=False)
    for signum in _SIGNALS:
        signal.signal(signum, _ignore)
    threading.Thread(target=_watch, args=(read,), name="twin signals", daemon=True).start()
    _state.installed = True


def _ignore(signum: int, frame: object) -> None:
    """The main thread's Python-level handler: nothing to do (the watcher acts on the byte
    the C-level handler wrote; recording here could win the race and leave it idle)."""


def _watch(read: int) -> None:
    # the one thread that takes the signals: one pending since install() comes now, its
    # byte written by the C-level handler (which runs in this thread) to the wakeup pipe
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _SIGNALS)
    while True:
        try:
            data = os.read(read, 64)
        except InterruptedError:
            continue
        if not data:
            return
        for signum in data:
            if signum in _SIGNALS and record(signum):
                with _state.lock:
                    waits = _state.depth > 0
                if waits:
                    timer = threading.Timer(GRACE_S, _hard_exit)
                    timer.daemon = True
                    timer.start()
                else:
                    _hard_exit()


def _hard_exit() -> None:
    """End the command now, from whatever thread (see the module). The main thread runs on
    meanwhile: from here what it (or a process it starts) prints goes nowhere, so the one
    line stays the last and only one."""
    with _state.lock:
        if _state.ending:
            return
        _state.ending = True
        _state.ender = threading.get_ident()
    name = _state.name or "SIGINT"
    # from here the command must end whatever fails on the way: the main thread, running on,
    # parks for good at its next park() (another thread is ending), so a step that raised
    # here would leave the command hanging, its children alive
    try:
        for stream in (sys.stdout, sys.stderr):
            with suppress(OSError, ValueError):
                stream.flush()
        err = _silence()
        end_children()
        # the hooks as they are now, just before the end: the main thread runs on meanwhile
        # (ending the children takes a tenth of a second), and a signal during prepare found no
        # run folder that the run may have made, and begun to record into, by now
        with _state.lock:
            hooks = list(_state.hooks)
        told = [_told(hook, name) for hook in hooks]
        with _state.lock:
            line = None if _state.said else next((t for t in told if t), None) or _line()
            _state.said = True
        if line is not None and err is not None:
            with suppress(OSError):
                os.write(err, (line + "\n").encode("utf-8", "replace"))
    finally:
        os._exit(exit_code(name))


def _told(hook: Callable[[str], str | None], name: str) -> str | None:
    try:
        return hook(name)
    except Exception:  # the ending must happen; a hook that failed leaves its file as it was
        return None


def _line() -> str:
    line = f"twin: interrupted by {_state.name or 'a signal'}"
    if _state.where and os.path.isdir(_state.where):  # not made yet: nothing was recorded
        line += f"; what was recorded so far is in {_state.where}"
    return line


def _silence() -> int | None:
    """Point this process's stdout and stderr at /dev/null (what starts from here inherits
    that too); a copy of stderr for the one line."""
    try:
        err = os.dup(2)
        null = os.open(os.devnull, os.O_WRONLY)
    except OSError:
        return None
    for fd in (1, 2):
        with suppress(OSError):
            os.dup2(null, fd)
    os.close(null)
    return err


def _no_more_workers() -> None:
    """A Dask nanny (a thread of this process) starts its worker again when it finds it dead,
    and multiprocessing its resource tracker: from here each such start fails at once (the
    executable it would start is /dev/null), and so does a build's next cmake, which the main
    thread, running on, could start between two FMUs (:func:`twin.fmu.toolchain.no_more_builds`),
    so killing them is not a race."""
    mp = sys.modules.get("multiprocessing")
    if mp is not None:
        with suppress(Exception):
            mp.set_executable(os.devnull)
    # loaded: a build may run; or still loading (the signal came during the imports, its body
    # not yet at no_more_builds): then no build has begun, and the exit comes milliseconds
    # from now, long before the run could reach one
    close = getattr(sys.modules.get("twin.fmu.toolchain"), "no_more_builds", None)
    if close is not None:
        close()


def _living(proc: Any) -> bool:
    """Not a zombie (a killed child stays one until this process reaps it: it has ended)."""
    import psutil

    try:
        return bool(proc.status() != psutil.STATUS_ZOMBIE)
    except psutil.Error:
        return False


def end_children() -> None:
    """Kill every process this one started, and theirs (SIGKILL: they have SIGTERM blocked).

    Every one is stopped first (SIGSTOP), round after round until no new one shows, then all
    are killed. Killed as found, a process could start one between the look and its kill
    (a build's make its compiler's linker): that one, orphaned, left the tree and outlived
    the command; a stopped process starts none, and what it started before stays below it,
    found in the next round. A few rounds: a thread of this process (a Dask nanny) may start
    one meanwhile."""
    try:
        import psutil  # distributed's dependency, so there with the twin
    except ImportError:  # pragma: no cover
        return
    _no_more_workers()
    stopped: dict[int, Any] = {}
    quiet = 0
    for _ in range(20):
        try:
            new = [
                c for c in psutil.Process().children(recursive=True) if c.pid not in stopped and _living(c)
            ]
        except psutil.Error:
            break
        quiet = 0 if new else quiet + 1
        if quiet == 3:
            break
        for child in new:
            with suppress(psutil.Error):
                child.suspend()
            stopped[child.pid] = child
        time.sleep(0.03)
    killed = list(stopped.values())
    for child in killed:
        with suppress(psutil.Error):
            child.kill()
    # a killed orphan may stay a zombie where the first process reaps none: no long wait
    psutil.wait_procs(killed, timeout=0.3)
