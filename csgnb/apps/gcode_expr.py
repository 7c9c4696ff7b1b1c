"""G-code lines as blocks: words, parameter assignments, O-words, and RS274NGC ``[ ]`` expressions.

:func:`read_block` turns one source line into a :class:`Block` whose word values are small
expression trees (tuples), evaluated later by :func:`evaluate` against the interpreter's
parameters -- so that ``#1 = [#1 + 1]`` inside a loop reads the value of each pass. The
syntax is LinuxCNC's: case and spaces do not matter, ``#n`` numbered / ``#<name>`` named /
``#<_name>`` global parameters, binary operators by precedence (``**``; ``* / MOD``; ``+ -``;
``EQ NE GT GE LT LE``; ``AND OR XOR``), left to right within one precedence, functions
``ABS ACOS ASIN ATAN[a]/[b] COS EXP FIX FUP ROUND LN SIN SQRT TAN EXISTS`` (angles in
degrees), and O-words (``o100 sub``, ``o<name> call [1] [2]``, ``if``/``while``/...).

Every number is read as a double and must be finite: ``X1`` followed by 400 zeros is an
error naming its line, not an infinity that surfaces later.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field

from csgnb.errors import CsgnbError

__all__ = ["Block", "GCodeError", "evaluate", "read_block", "strip_comments"]

MAX_NESTING = 64
"""Deepest ``[ ]`` nesting read (a bound on the recursion of the reader and the evaluator)."""

TOLERANCE_EQUAL = 1e-4
"""``EQ`` / ``NE`` / ``GE`` / ``LE`` compare within this (LinuxCNC's ``TOLERANCE_EQUAL``)."""

_NUMBER = re.compile(r"(?:\d+\.?\d*|\.\d+)")
_KEYWORDS = ("endsub", "endwhile", "endrepeat", "endif", "elseif", "else", "sub", "call", "return", "if", "while",
             "do", "repeat", "break", "continue")
_FUNCTIONS = ("atan", "abs", "acos", "asin", "cos", "exp", "fix", "fup", "round", "ln", "sin", "sqrt", "tan",
              "exists")
# (precedence, token): higher binds tighter; equal precedences associate left to right (LinuxCNC's precedence()).
_OPERATORS = [("**", 6), ("*", 5), ("/", 5), ("mod", 5), ("+", 4), ("-", 4), ("eq", 3), ("ne", 3), ("gt", 3),
              ("ge", 3), ("lt", 3), ("le", 3), ("and", 2), ("or", 2), ("xor", 2)]


class GCodeError(CsgnbError):
    """A G-code line could not be used; ``line`` is its 1-based number, ``word`` the offending word (if one)."""

    def __init__(self, line: int, message: str, word: str | None = None) -> None:
        self.line = line
        self.word = word
        super().__init__(f"line {line}: {message}")


@dataclass
class Block:
    """One source line, read but not evaluated.

    Attributes
    ----------
    line : int
        1-based source line.
    delete : bool
        The line starts with ``/`` (block delete).
    label : int or None
        The ``N`` number.
    oword : tuple or None
        ``(name, keyword, args)``: the O-word's name (digits or ``<text>``), its keyword
        (``sub``, ``call``, ``if``, ...) and its ``[ ]`` argument expressions.
    words : list of (letter, expression, text)
        Upper-case letter, expression tree, and the word as written (for messages).
    assigns : list of (index expression or name, expression, text)
        ``#...=`` assignments, applied after the line (RS274NGC).
    percent : bool
        A ``%`` tape mark line.
    """

    line: int
    delete: bool = False
    label: int | None = None
    oword: tuple | None = None
    words: list = field(default_factory=list)
    assigns: list = field(default_factory=list)
    percent: bool = False

    @property
    def empty(self) -> bool:
        return self.oword is None and not self.words and not self.assigns


def strip_comments(text: str, line: int) -> str:
    """The line without its ``( ... )`` and ``; ...`` comments (nested or unclosed ones are errors)."""
    if "(" not in text and ")" not in text and ";" not in text:
        return text
    out = []
    depth = False
    for ch in text:
        if depth:
            if ch == "(":
                raise GCodeError(line, "a comment opens inside a comment '(' ... '(' (nested comments are not G-code)")
            if ch == ")":
                depth = False
            continue
        if ch == "(":
            depth = True
        elif ch == ";":
            break
        elif ch == ")":
            raise GCodeError(line, "a ')' closes no comment")
        else:
            out.append(ch)
    if depth:
        raise GCodeError(line, "a comment '(' is not closed on its line")
    return "".join(out)


_SIMPLE_LINE = re.compile(r"(?:[a-np-z][+-]?(?:\d+\.?\d*|\.\d+))+")
_SIMPLE_WORD = re.compile(r"([a-z])([+-]?)(\d+\.?\d*|\.\d+)")


def _finite_number(text: str, line: int) -> float:
    value = float(text)
    if not math.isfinite(value):
        shown = text if len(text) <= 16 else f"{text[:8]}...({len(text)} digits)"
        raise GCodeError(line, f"the number {shown} is too large for a double (it overflows to infinity); "
                         "write a value of a sensible size", shown)
    return value


class _Reader:
    def __init__(self, s: str, line: int) -> None:
        self.s, self.pos, self.line, self.depth = s, 0, line, 0

    def fail(self, what: str):
        bad = self.s[self.pos:self.pos + 12] or "the end of the line"
        raise GCodeError(self.line, f"cannot read {bad!r}: {what}", bad)

    def peek(self, text: str) -> bool:
        return self.s.startswith(text, self.pos)

    def take(self, text: str) -> bool:
        if self.s.startswith(text, self.pos):
            self.pos += len(text)
            return True
        return False

    def number(self) -> tuple:
        m = _NUMBER.match(self.s, self.pos)
        if m is None:
            self.fail("expected a number")
        self.pos = m.end()
        return ("num", _finite_number(m.group(0), self.line))

    def real(self) -> tuple:
        """A real value: a number, ``[expression]``, ``#parameter``, a signed value, or a function call."""
        s, p = self.s, self.pos
        if p >= len(s):
            self.fail("expected a value")
        ch = s[p]
        if ch == "[":
            return self.bracket()
        if ch == "#":
            self.pos += 1
            return ("param", self.param_ref())
        if ch in "+-":
            self.pos += 1
            v = self.real()
            return v if ch == "+" else ("neg", v)
        if ch.isdigit() or ch == ".":
            return self.number()
        for name in _FUNCTIONS:
            if s.startswith(name + "[", p):
                self.pos += len(name)
                if name == "exists":
                    self.take("[")
                    if not self.take("#<"):
                        self.fail("EXISTS takes a named parameter, e.g. EXISTS[#<name>]")
                    ref = self.name()
                    if not self.take("]"):
                        self.fail("expected ']' after EXISTS[#<name>")
                    return ("exists", ref)
                arg = self.bracket()
                if name == "atan":
                    if not self.take("/"):
                        self.fail("ATAN takes two arguments: ATAN[y]/[x]")
                    return ("atan", arg, self.bracket())
                return ("fn", name, arg)
        self.fail("expected a number, [expression], #parameter or a function such as SIN[...]")

    def name(self) -> str:
        end = self.s.find(">", self.pos)
        if end < 0:
            self.fail("a parameter name #<... is not closed with '>'")
        name = self.s[self.pos:end]
        if not name:
            self.fail("an empty parameter name #<>")
        self.pos = end + 1
        return name

    def param_ref(self):
        """After ``#``: a name (str) or an index expression (tuple)."""
        if self.take("<"):
            return self.name()
        return self.real()

    def bracket(self) -> tuple:
        if not self.take("["):
            self.fail("expected '['")
        self.depth += 1
        if self.depth > MAX_NESTING:
            self.fail(f"expressions nest deeper than {MAX_NESTING} brackets")
        v = self.expression()
        if not self.take("]"):
            self.fail("expected an operator or ']'")
        self.depth -= 1
        return v

    def operator(self):
        for tok, prec in _OPERATORS:
            if self.s.startswith(tok, self.pos):
                return tok, prec
        return None

    def expression(self) -> tuple:
        # Operator precedence parsing, left-associative at every level (RS274NGC, LinuxCNC's read_real_expression).
        values = [self.real()]
        ops: list[tuple[str, int]] = []
        while True:
            op = self.operator()
            if op is None:
                break
            self.pos += len(op[0])
            while ops and ops[-1][1] >= op[1]:
                b, a = values.pop(), values.pop()
                values.append(("bin", ops.pop()[0], a, b))
            ops.append(op)
            values.append(self.real())
        while ops:
            b, a = values.pop(), values.pop()
            values.append(("bin", ops.pop()[0], a, b))
        return values[0]


def read_block(raw: str, line: int) -> Block:
    """The :class:`Block` of one source line (comments removed; syntax errors name the line)."""
    try:
        return _read_block(raw, line)
    except RecursionError:
        raise GCodeError(line, "the line nests signs, parameters or brackets too deeply to read") from None


def _read_block(raw: str, line: int) -> Block:
    code = re.sub(r"\s+", "", strip_comments(raw, line)).lower()
    block = Block(line)
    if _SIMPLE_LINE.fullmatch(code):
        # The common line (letters and plain numbers only): the same words as the general reader, without it.
        # N stays a word here; the interpreter reads it as the label.
        for letter, sign, digits in _SIMPLE_WORD.findall(code):
            value = _finite_number(digits, line)
            block.words.append((letter.upper(), ("num", -value if sign == "-" else value),
                                letter.upper() + sign + digits))
        return block
    r = _Reader(code, line)
    if r.take("/"):
        block.delete = True
    if r.peek("n") and r.pos + 1 < len(code) and (code[r.pos + 1].isdigit() or code[r.pos + 1] == "."):
        r.pos += 1
        start = r.pos
        value = r.number()[1]
        if value != int(value):
            raise GCodeError(line, f"a line number must be a non-negative integer, got N{code[start:r.pos]}",
                             f"N{code[start:r.pos]}")
        block.label = int(value)
    if r.take("o"):
        if r.take("<"):
            name = "<" + r.name() + ">"
        elif r.peek("["):
            name = ("expr", r.bracket())  # o[150 + 50] call: a computed number, for calls only
        else:
            m = re.compile(r"\d+").match(code, r.pos)
            if m is None:
                r.fail("an O-word is o<name> or o followed by a number, e.g. o100 sub")
            name = str(int(m.group(0)))
            r.pos = m.end()
        keyword = next((k for k in _KEYWORDS if code.startswith(k, r.pos)), None)
        if keyword is None and r.pos == len(code) and isinstance(name, str) and name.isdigit():
            block.oword = (name, "program", [])  # O1001 alone: a Fanuc/Haas program number
            return block
        if keyword is None:
            r.fail("expected an O-word keyword (sub, endsub, call, return, if, elseif, else, endif, while, "
                   "endwhile, do, repeat, endrepeat, break, continue)")
        r.pos += len(keyword)
        args = []
        while r.peek("["):
            args.append(r.bracket())
        if r.pos != len(code):
            r.fail(f"nothing may follow o{name} {keyword} but its [ ] arguments")
        if isinstance(name, tuple) and keyword != "call":
            raise GCodeError(line, f"a computed O-word number o[...] is supported with call only, not {keyword}",
                             "o[")
        takes = {"call": None, "if": 1, "elseif": 1, "while": 1, "repeat": 1, "return": (0, 1), "endsub": (0, 1)}
        want = takes.get(keyword, 0)
        if want is not None:
            ok = len(args) in want if isinstance(want, tuple) else len(args) == want
            if not ok:
                raise GCodeError(line, f"o{name} {keyword} takes {want if not isinstance(want, tuple) else 'at most 1'}"
                                 f" [ ] argument(s), got {len(args)}", f"o{name}")
        if keyword == "call" and len(args) > 30:
            raise GCodeError(line, f"o{name} call passes {len(args)} arguments; at most 30 (#1..#30)", f"o{name}")
        block.oword = (name, keyword, args)
        return block
    while r.pos < len(code):
        ch = code[r.pos]
        if ch == "#":
            r.pos += 1
            start = r.pos - 1
            ref = r.param_ref()
            if not r.take("="):
                r.fail("a parameter outside a word is an assignment: #1 = 2.5")
            block.assigns.append((ref, r.real(), code[start:r.pos]))
        elif ch.isalpha() and ch.isascii():
            r.pos += 1
            start = r.pos
            value = r.real()
            block.words.append((ch.upper(), value, ch.upper() + code[start:r.pos]))
        elif ch in "@^":
            r.fail("polar coordinates (@ radius, ^ angle) are not supported: give X Y")
        else:
            r.fail("every word is a letter followed by a number (e.g. X1.5), [expression] or #parameter")
    return block


def _truth(v: float) -> float:
    return 0.0 if v == 0.0 else 1.0


def evaluate(node: tuple, env, line: int, word: str | None = None) -> float:
    """The value of an expression tree; ``env`` reads parameters (``env.read(index)``, ``env.read_named(name)``,
    ``env.exists(name)``). Domain errors (division by zero, SQRT of a negative, ...) name the line."""

    def bad(msg: str):
        raise GCodeError(line, msg + (f" (in {word})" if word else ""), word)

    def ev(n: tuple) -> float:
        tag = n[0]
        if tag == "num":
            return n[1]
        if tag == "neg":
            return -ev(n[1])
        if tag == "param":
            ref = n[1]
            return env.read_named(ref, line) if isinstance(ref, str) else env.read(ev(ref), line)
        if tag == "exists":
            return 1.0 if env.exists(n[1]) else 0.0
        if tag == "atan":
            return math.degrees(math.atan2(ev(n[1]), ev(n[2])))
        if tag == "fn":
            name, x = n[1], ev(n[2])
            if name == "abs":
                return abs(x)
            if name in ("acos", "asin"):
                if not -1.0 <= x <= 1.0:
                    bad(f"{name.upper()}[{x:g}]: the argument must lie in [-1, 1]")
                return math.degrees(math.acos(x) if name == "acos" else math.asin(x))
            if name in ("cos", "sin", "tan"):
                return getattr(math, name)(math.radians(x))
            if name == "exp":
                if x > 709.0:
                    bad(f"EXP[{x:g}] overflows a double")
                return math.exp(x)
            if name == "fix":
                return float(math.floor(x))
            if name == "fup":
                return float(math.ceil(x))
            if name == "round":
                return float(math.floor(x + 0.5) if x >= 0 else -math.floor(-x + 0.5))
            if name == "ln":
                if not x > 0:
                    bad(f"LN[{x:g}]: the argument must be positive")
                return math.log(x)
            if name == "sqrt":
                if x < 0:
                    bad(f"SQRT[{x:g}]: the argument must not be negative")
                return math.sqrt(x)
        if tag == "bin":
            op, a, b = n[1], ev(n[2]), ev(n[3])
            if op == "+":
                return a + b
            if op == "-":
                return a - b
            if op == "*":
                return a * b
            if op == "/":
                if b == 0:
                    bad(f"division by zero ({a:g} / 0)")
                return a / b
            if op == "mod":
                if b == 0:
                    bad(f"{a:g} MOD 0: modulo by zero")
                m = math.fmod(a, b)
                return m + abs(b) if m < 0 else m
            if op == "**":
                if a < 0 and b != int(b):
                    bad(f"{a:g} ** {b:g}: a negative base needs an integer exponent")
                if a == 0 and b < 0:
                    bad("0 ** a negative exponent: division by zero")
                try:
                    return math.pow(a, b)
                except OverflowError:
                    bad(f"{a:g} ** {b:g} overflows a double")
            if op == "eq":
                return 1.0 if abs(a - b) < TOLERANCE_EQUAL else 0.0
            if op == "ne":
                return 0.0 if abs(a - b) < TOLERANCE_EQUAL else 1.0
            if op == "gt":
                return 1.0 if a > b else 0.0
            if op == "lt":
                return 1.0 if a < b else 0.0
            if op == "ge":
                return 1.0 if a > b or abs(a - b) < TOLERANCE_EQUAL else 0.0
            if op == "le":
                return 1.0 if a < b or abs(a - b) < TOLERANCE_EQUAL else 0.0
            if op == "and":
                return _truth(a) * _truth(b)
            if op == "or":
                return 1.0 if a != 0 or b != 0 else 0.0
            if op == "xor":
                return 1.0 if (a != 0) != (b != 0) else 0.0
        raise AssertionError(f"unknown expression node {n!r}")

    try:
        value = ev(node)
    except RecursionError:
        bad("the expression nests too deeply to evaluate")
    if not math.isfinite(value):
        bad("the value overflows a double (it is infinite or NaN)")
    return value


def positive_count(values: dict, letter: str, line: int, what: str) -> int:
    """The positive integer given by word ``letter`` of ``values`` ({letter: (value, word)}), e.g. an arc's P turns
    or a cycle's L repeats; 1 when absent; a :class:`GCodeError` naming ``what`` otherwise."""
    if letter not in values:
        return 1
    n, word = values[letter]
    if n != int(n) or n < 1:
        raise GCodeError(line, f"{what} must be a positive integer, got {word}", word)
    return int(n)
