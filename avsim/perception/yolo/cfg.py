"""Darknet `.cfg` files: `[section]` headers followed by `key = value` lines.

A cfg is a list of sections; the first is `[net]` (input size and channels, training
settings), each later one a layer, numbered from 0 in file order (the numbers that
`[route] layers` and `[shortcut] from` refer to). `#` and `;` start comments. Values stay
strings here; `Section`'s getters parse them and name the file, line and key when one is
malformed, so a user's broken cfg is refused in one line.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from avsim.errors import AvsimError


class DarknetFileError(AvsimError):
    """A Darknet .cfg, .weights or .names file that cannot be read as one."""


@dataclass
class Section:
    """One `[kind]` block: its options (key -> raw string) and where it starts in the file."""

    kind: str
    line: int
    source: str
    options: dict[str, str] = field(default_factory=dict)

    def _where(self, key: str) -> str:
        return f"{self.source}: [{self.kind}] at line {self.line}, key {key!r}"

    def text(self, key: str, default: str | None = None) -> str:
        """The option's text, or `default`; a missing option without a default is a one-line `DarknetFileError`."""
        if key in self.options:
            return self.options[key]
        if default is None:
            raise DarknetFileError(f"{self._where(key)} is required but missing; add it to the cfg")
        return default

    def _number(self, key: str, default: object, convert: type, what: str):
        raw = self.text(key, None if default is None else str(default))
        try:
            return convert(raw)
        except ValueError:
            raise DarknetFileError(f"{self._where(key)}: {raw!r} is not {what}; fix the cfg") from None

    def int(self, key: str, default: int | None = None) -> int:
        """The option as an integer, or `default`; missing or malformed, a one-line `DarknetFileError`."""
        return self._number(key, default, int, "an integer")

    def float(self, key: str, default: float | None = None) -> float:
        """The option as a number, or `default`; missing or malformed, a one-line `DarknetFileError`."""
        return self._number(key, default, float, "a number")

    def _numbers(self, key: str, convert: type, what: str) -> tuple:
        raw = self.text(key)
        try:
            return tuple(convert(v) for v in raw.split(",") if v.strip())
        except ValueError:
            raise DarknetFileError(f"{self._where(key)}: {raw!r} is not a comma-separated list of {what}; "
                                   "fix the cfg") from None

    def ints(self, key: str, default: tuple[int, ...] | None = None) -> tuple[int, ...]:
        """The option's comma-separated integers, or `default` when it is absent."""
        if key not in self.options and default is not None:
            return default
        return self._numbers(key, int, "integers")

    def floats(self, key: str) -> tuple[float, ...]:
        """The option's comma-separated numbers (required)."""
        return self._numbers(key, float, "numbers")

    def fail(self, message: str) -> DarknetFileError:
        """An error about this section, naming the file and line."""
        return DarknetFileError(f"{self.source}: [{self.kind}] at line {self.line}: {message}")


def parse_cfg_text(text: str, source: str = "<cfg>") -> list[Section]:
    """The sections of a cfg's text, in order; `source` names it in errors."""
    sections: list[Section] = []
    for number, raw in enumerate(text.splitlines(), start=1):
        line = raw.split("#", 1)[0].split(";", 1)[0].strip()
        if not line:
            continue
        if line.startswith("["):
            if not line.endswith("]") or len(line) < 3:
                raise DarknetFileError(f"{source}: line {number}: {raw.strip()!r} is not a [section] header; fix the cfg")
            sections.append(Section(line[1:-1].strip().lower(), number, source))
        elif "=" in line and sections:
            key, value = line.split("=", 1)
            sections[-1].options[key.strip()] = value.strip()
        else:
            raise DarknetFileError(f"{source}: line {number}: {raw.strip()!r} is neither a [section] nor key=value "
                                   "inside one; fix the cfg")
    if not sections or sections[0].kind not in ("net", "network"):
        raise DarknetFileError(f"{source}: a Darknet cfg starts with a [net] section; this one "
                               f"{'is empty' if not sections else f'starts with [{sections[0].kind}]'}")
    return sections


def parse_cfg(path: str | Path) -> list[Section]:
    """The sections of the cfg file at `path` ([net] first, then the layers)."""
    path = Path(path)
    try:
        text = path.read_text(encoding="utf-8", errors="strict")
    except FileNotFoundError:
        raise DarknetFileError(f"Darknet cfg {path} does not exist; check perception.yolo_cfg") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise DarknetFileError(f"Darknet cfg {path} cannot be read as text ({exc}); check perception.yolo_cfg") from None
    return parse_cfg_text(text, str(path))
