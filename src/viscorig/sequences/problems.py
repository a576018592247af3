"""Every problem of a TOML file at once, each with its file, line, field and a way to fix it.

A technician who wrote three mistakes should learn of all three in one go, in the order they
appear in the file, each with the line to look at and, where a name was misspelt, the name
meant (``difflib``). :class:`Problems` collects them while a file is read;
:class:`FileCheckError` is the :class:`~viscorig.errors.InputError` that carries them all.
"""

from __future__ import annotations

import difflib
import re
from collections.abc import Iterable
from dataclasses import dataclass

from viscorig.errors import InputError

#: A path to a value: ``("steps", 3, "level")``.
Path = tuple[str | int, ...]

_ARRAY_TABLE = re.compile(r"^\s*\[\[\s*(?P<name>[^\]]+?)\s*\]\]\s*(#.*)?$")
_TABLE = re.compile(r"^\s*\[\s*(?P<name>[^\]\[]+?)\s*\]\s*(#.*)?$")
_KEY = re.compile(r"^\s*(?P<key>[A-Za-z0-9_.\-\"' ]+?)\s*=(?P<value>.*)$")


def field_name(path: Path) -> str:
    """``("steps", 3, "level")`` -> ``"steps[3].level"``."""
    text = ""
    for part in path:
        if isinstance(part, int):
            text += f"[{part}]"
        else:
            text += f".{part}" if text else part
    return text


def _key_parts(key: str) -> tuple[str, ...]:
    return tuple(part.strip().strip("\"'") for part in key.split("."))


def _opens(value: str) -> tuple[int, bool]:
    """Bracket depth change and whether a multi-line string opens, for one line of a value
    (characters inside single-line strings and comments are ignored)."""
    depth, quote, index = 0, "", 0
    while index < len(value):
        char = value[index]
        if not quote and value.startswith(('"""', "'''"), index):
            triple = value[index:index + 3]
            end = value.find(triple, index + 3)
            if end < 0:
                return depth, True
            index = end + 3
            continue
        if quote:
            if char == "\\" and quote == '"':
                index += 1
            elif char == quote:
                quote = ""
        elif char in "\"'":
            quote = char
        elif char == "#":
            break
        elif char in "[{":
            depth += 1
        elif char in "]}":
            depth -= 1
        index += 1
    return depth, False


class LineIndex:
    """Where each table and key of a TOML text starts (1-based lines), to point at problems.

    A small scanner of the shapes TOML files of this project use (top-level keys, ``[table]``,
    ``[[array]]`` tables, multi-line arrays and strings); a value it cannot place is given the
    line of the closest enclosing table it found.
    """

    def __init__(self, text: str) -> None:
        self.lines: dict[Path, int] = {}
        counts: dict[tuple[str, ...], int] = {}
        current: Path = ()
        depth, in_string = 0, False
        for number, line in enumerate(text.splitlines(), start=1):
            if in_string:
                in_string = line.count('"""') % 2 == 0 and line.count("'''") % 2 == 0
                continue
            if depth > 0:
                change, in_string = _opens(line)
                depth = max(depth + change, 0)
                continue
            array = _ARRAY_TABLE.match(line)
            table = None if array else _TABLE.match(line)
            if array or table:
                parts = _key_parts((array or table)["name"])  # type: ignore[index]
                name = self._nested(parts, counts)
                if array:
                    index = counts.get(name, 0)
                    counts[name] = index + 1
                    current = (*name, index)
                else:
                    current = name
                self.lines.setdefault(current, number)
                continue
            key = _KEY.match(line)
            if key:
                self.lines.setdefault((*current, *_key_parts(key["key"])), number)
                change, in_string = _opens(key["value"])
                depth = max(change, 0)

    @staticmethod
    def _nested(name: tuple[str, ...], counts: dict[tuple, int]) -> tuple:
        """A table name inside array tables (``steps.steps``) as a path through the current
        element of each (``("steps", 4, "steps")``)."""
        resolved: tuple = ()
        for part in name[:-1]:
            resolved = (*resolved, part)
            if resolved in counts:
                resolved = (*resolved, counts[resolved] - 1)
        return (*resolved, name[-1])

    def line(self, path: Path) -> int | None:
        """The line of ``path``, or of its closest enclosing table; None when none is known."""
        for end in range(len(path), 0, -1):
            found = self.lines.get(tuple(path[:end]))
            if found is not None:
                return found
        return None


@dataclass(frozen=True)
class Problem:
    """One thing wrong in a file: where, what, and how to fix it."""

    file: str
    line: int | None
    field: str
    message: str
    hint: str = ""
    """A did-you-mean or the fix, or ""."""

    @property
    def where(self) -> str:
        """``paper.toml:57: steps[3].level`` (no line when unknown, no field for the file)."""
        place = self.file if self.line is None else f"{self.file}:{self.line}"
        return f"{place}: {self.field}" if self.field else place

    @property
    def text(self) -> str:
        """The message with its hint."""
        return f"{self.message}; {self.hint}" if self.hint else self.message

    def __str__(self) -> str:
        return f"{self.where}: {self.text}"

    def as_dict(self) -> dict[str, object]:
        """For ``--json``."""
        return {"file": self.file, "line": self.line, "field": self.field,
                "message": self.message, "hint": self.hint}


#: Characters of a value a problem quotes; a longer one is cut with "…" (a list of 5,000
#: temperatures was quoted whole, 25 KB on one line).
QUOTED_CHARACTERS = 60


def quoted(value: object) -> str:
    """``repr(value)``, cut to :data:`QUOTED_CHARACTERS` with "…"."""
    text = repr(value)
    return text if len(text) <= QUOTED_CHARACTERS else text[:QUOTED_CHARACTERS - 1] + "…"


def did_you_mean(word: object, known: Iterable[str], cutoff: float = 0.6) -> str:
    """``"did you mean 'specimen'?"`` for the known name closest to ``word``, or ""."""
    if not isinstance(word, str):
        return ""
    close = difflib.get_close_matches(word, list(known), n=1, cutoff=cutoff)
    if not close:
        close = [name for name in known if name.lower() == word.lower()]
    return f"did you mean {close[0]!r}?" if close else ""


class FileCheckError(InputError):
    """Every problem found in a file; its message is the first, with how many more follow.

    Parameters
    ----------
    problems
        All of them; kept in file order in ``problems``.
    check_command
        The command that lists them all, named in the message when there are more than one
        (default ``viscorig check FILE`` of the first; "" for none).
    """

    def __init__(self, problems: list[Problem], check_command: str | None = None) -> None:
        self.problems = sorted(problems, key=lambda p: (p.file, p.line or 0))
        first = self.problems[0]
        more = len(self.problems) - 1
        command = f"viscorig check {first.file}" if check_command is None else check_command
        listed = f": '{command}' lists them all" if command else ""
        suffix = f" (and {more} more problem{'s' if more > 1 else ''}{listed})" if more else ""
        super().__init__(first.text + suffix, first.where)


class Problems:
    """Collects the problems of one TOML text while it is read.

    Parameters
    ----------
    source
        The file's name, as messages show it.
    text
        The TOML text, to find the line of each field.
    """

    def __init__(self, source: str, text: str = "") -> None:
        self.source = source
        self.index = LineIndex(text)
        self.items: list[Problem] = []
        self._seen: set[tuple[str, str]] = set()

    def add(self, path: Path, message: str, hint: str = "") -> None:
        """Record a problem of the value at ``path`` (a value taken from ``[defaults]`` has the
        defaults' path, so a wrong default is reported once, not once per step)."""
        name = field_name(path)
        if (name, message) in self._seen:
            return
        self._seen.add((name, message))
        self.items.append(Problem(self.source, self.index.line(path), name, message, hint))

    def __bool__(self) -> bool:
        return bool(self.items)

    def __len__(self) -> int:
        return len(self.items)

    def raise_if_any(self) -> None:
        """Raise :class:`FileCheckError` when a problem was found.

        Raises
        ------
        FileCheckError
            One or more problems.
        """
        if self.items:
            raise FileCheckError(self.items)
