"""Text helpers the program writers and readers share: files split to a size, bracketed values, arguments."""

from __future__ import annotations

import re

import numpy as np

from sprayplan.programs.model import JOINT, ProgramError, parse_number

#: A move after which a program may be cut into the next file: the robot stands still there, the gun closed.
_CUT_AFTER = ("retract", "home")


def program_lines(path) -> list[tuple[int, str]]:
    """A written program's lines, numbered from 1: ASCII, no tabs or carriage returns, ending with a line break
    (as sprayplan writes them); anything else a :class:`ProgramError` naming the file."""
    from sprayplan.checks import check_input_file

    check_input_file(path)
    try:
        text = path.read_text(encoding="ascii")
    except FileNotFoundError:
        raise ProgramError(path, 0, "no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ProgramError(path, 0, f"not a readable text file ({exc})") from None
    if "\t" in text or "\r" in text or not text.endswith("\n"):
        raise ProgramError(path, 0, "holds tabs or carriage returns, or does not end with a line break")
    return [(k + 1, line) for k, line in enumerate(text.split("\n")[:-1])]


def chunks(moves: list, cost, limit: int) -> list[list]:
    """``moves`` cut into consecutive chunks of total ``cost(move)`` at most ``limit``, cut only after a retract
    or a home move (a run is never cut: ``build.run_limit`` keeps each run within a file)."""
    blocks, block = [], []
    for move in moves:
        block.append(move)
        if move.role in _CUT_AFTER:
            blocks.append(block)
            block = []
    if block:
        blocks.append(block)
    out, current, used = [], [], 0
    for block in blocks:
        size = sum(cost(m) for m in block)
        if current and used + size > limit:
            out.append(current)
            current, used = [], 0
        current += block
        used += size
    if current:
        out.append(current)
    return out


def is_joint(move) -> bool:
    return move.kind == JOINT


_TOKEN = re.compile(r'\s*(\[|\]|,|"[^"\n]*"|TRUE\b|FALSE\b|[+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)')


def aggregate(text: str, where: tuple):
    """A bracketed value (``[[1, 2], [TRUE, "x"]]``) as nested lists of floats, bools and strings; anything else
    in the text is a :class:`ProgramError` at ``where`` (path, line)."""
    pos = 0

    def token():
        nonlocal pos
        match = _TOKEN.match(text, pos)
        if not match:
            raise ProgramError(*where, f"cannot read {text[pos:].strip()[:40]!r} in {text.strip()[:60]!r}")
        pos = match.end()
        return match.group(1)

    def value():
        tok = token()
        if tok == "[":
            items = [value()]
            while True:
                tok = token()
                if tok == "]":
                    return items
                if tok != ",":
                    raise ProgramError(*where, f"expected , or ] in {text.strip()[:60]!r}")
                items.append(value())
        if tok in ("]", ","):
            raise ProgramError(*where, f"unexpected {tok!r} in {text.strip()[:60]!r}")
        if tok == "TRUE" or tok == "FALSE":
            return tok == "TRUE"
        if tok.startswith('"'):
            return tok[1:-1]
        return parse_number(tok, where)

    out = value()
    if text[pos:].strip():
        raise ProgramError(*where, f"unexpected {text[pos:].strip()[:40]!r} after {text[:pos].strip()[-40:]!r}")
    return out


def numbers(value, shape: tuple, what: str, where: tuple) -> np.ndarray:
    """A nested list of numbers (no bools or strings) of exactly ``shape``, as floats."""
    try:
        if _has_other(value):
            raise ValueError
        array = np.array(value, dtype=float)
    except (ValueError, TypeError):
        array = None
    if array is None or array.shape != shape:
        raise ProgramError(*where, f"{what} must be {_shape_text(shape)}, got {value!r}"[:200])
    return array


def _has_other(value) -> bool:
    if isinstance(value, list):
        return any(_has_other(v) for v in value)
    return isinstance(value, (bool, str))


def _shape_text(shape: tuple) -> str:
    if len(shape) == 1:
        return f"{shape[0]} numbers"
    return f"{shape[0]} lists of {shape[1]} numbers"


def split_arguments(text: str, where: tuple) -> list[str]:
    """The comma-separated arguments of a statement, split outside brackets and quotes."""
    out, depth, start, quoted = [], 0, 0, False
    for i, ch in enumerate(text):
        if ch == '"':
            quoted = not quoted
        elif quoted:
            continue
        elif ch in "[({":
            depth += 1
        elif ch in "])}":
            depth -= 1
            if depth < 0:
                raise ProgramError(*where, f"unbalanced brackets in {text.strip()[:60]!r}")
        elif ch == "," and depth == 0:
            out.append(text[start:i].strip())
            start = i + 1
    if depth or quoted:
        raise ProgramError(*where, f"unbalanced brackets or quotes in {text.strip()[:60]!r}")
    out.append(text[start:].strip())
    return out
