"""One error hierarchy for the whole twin.

Every error the twin raises on purpose derives from :class:`TwinError`. Errors about the
user's input (scenario files, command-line values, missing tools) are :class:`ConfigError`
and map to exit code 2; errors that happen while a run is under way are :class:`RunError`
and map to exit code 1. Like pint, each also subclasses the matching builtin so callers
that only know ``ValueError`` or ``RuntimeError`` still catch them.
"""

from __future__ import annotations

from collections.abc import Iterable


class TwinError(Exception):
    """Base class of every error raised by the twin on purpose."""

    exit_code = 1


#: the longest file name, key or message a problem line shows of each (a 5000-digit number or
#: a key of a megabyte would otherwise make the "one line" unreadable)
MAX_SHOWN = 500


def _one_line(text: str | None) -> str | None:
    if text is None:
        return None
    text = text.replace("\r", "\\r").replace("\n", "\\n")
    if len(text) > MAX_SHOWN:
        text = f"{text[: MAX_SHOWN - 80]}... ({len(text)} characters)"
    return text


class ConfigError(TwinError, ValueError):
    """Bad input: a scenario file, a ``--set`` value, a command-line argument.

    ``source`` names the file (or ``--set``/argument), ``key`` the dotted key; ``str()`` is one line.
    """

    exit_code = 2

    def __init__(self, message: str, *, source: str | None = None, key: str | None = None) -> None:
        # one problem, one line: a line break inside a quoted TOML key or a value is shown escaped
        source, key, message = (_one_line(x) for x in (source, key, message))
        self.source = source
        self.key = key
        self.message = message
        where = ": ".join(p for p in (source, key) if p)
        super().__init__(f"{where}: {message}" if where else message)


class ConfigErrors(ConfigError):
    """Several input problems, all reported at once (one line each)."""

    def __init__(self, problems: list[ConfigError]) -> None:
        self.problems = list(problems)
        first = self.problems[0]
        super().__init__(first.message, source=first.source, key=first.key)
        self.args = ("\n".join(str(p) for p in self.problems),)

    def __str__(self) -> str:
        return "\n".join(str(p) for p in self.problems)


class UnitError(ConfigError):
    """A unit that is not known, or two units of different dimensions (:mod:`twin.units`)."""


class CheckpointError(ConfigError):
    """A checkpoint that cannot be trusted or read (a changed or damaged part, another format or
    version, an old pickle, a scenario changed since it was taken): refused, never executed."""


class UnsafeCacheError(ConfigError, PermissionError):
    """The cache of built binaries is not private (another user owns it, or others may write
    into it): nothing is loaded from it, since a planted library would run in this process."""


class ToolMissingError(ConfigError, FileNotFoundError):
    """A build tool (C compiler, cmake) is not installed; the message says what to install."""


class BuildError(TwinError, RuntimeError):
    """Building an FMU failed (compiler error); carries the build log tail."""


class RunError(TwinError, RuntimeError):
    """A failure while the co-simulation runs."""


class FMUError(RunError):
    """An FMU returned fmi2Error/fmi2Fatal/fmi2Discard or a non-finite output.

    Names the FMU instance, the FMI call and the simulation time.
    """

    def __init__(self, instance: str, call: str, time_s: float, detail: str = "") -> None:
        self.instance = instance
        self.call = call
        self.time_s = time_s
        self.detail = detail
        msg = f"FMU '{instance}' failed in {call} at t = {time_s:.6g} s"
        super().__init__(f"{msg}: {detail}" if detail else msg)
        # keep the constructor's arguments, so copies made by schedulers (simpy re-raises a
        # copy built from .args) carry the same information
        self.args = (instance, call, time_s, detail)

    def __str__(self) -> str:
        msg = f"FMU '{self.instance}' failed in {self.call} at t = {self.time_s:.6g} s"
        return f"{msg}: {self.detail}" if self.detail else msg


def did_you_mean(word: str, known: Iterable[str]) -> str:
    """`` (did you mean 'x'?)`` for the closest of ``known`` to a misspelt ``word``, or ``""``:
    what a message about an unknown name adds."""
    import difflib

    close = difflib.get_close_matches(word, sorted(known), n=1, cutoff=0.7)
    return f" (did you mean {close[0]!r}?)" if close else ""
