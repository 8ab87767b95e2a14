"""Reading one RS274/NGC line into a :class:`Block`: words, parameter settings, O-word and comment.

This is the lexical half of :mod:`fusioncut.io.gcode`; it knows nothing about machine state. A line is
read once and kept: loops and subroutines execute the same :class:`Block` again, so values that
depend on parameters are kept as compiled expressions (plain Python closures over a parameter store)
and evaluated every time the block runs.

Syntax follows LinuxCNC's dialect of RS274/NGC (the reference for our tests):

* letters are case-insensitive and white space outside comments is ignored, also inside numbers
  (``X 1 0.5`` is ``X10.5``);
* ``(...)`` comments (no nesting) and ``;`` comments to the end of the line; the last comment of a
  line is kept as the block's comment (``(msg,...)`` and friends are just comments here);
* an optional ``/`` (block delete) and ``N`` line number start the line;
* a real value is a number (no exponent), ``[expression]``, ``#parameter``, a unary function
  ``NAME[expression]`` (``ATAN[y]/[x]`` takes two), or one of these after a ``+``/``-`` sign;
* parameters are ``#n`` (1..5601), ``#<name>`` (local) / ``#<_name>`` (global), ``#[expr]`` and
  ``##n`` (indirect);
* binary operators, from the most to the least binding: ``**``; ``* / MOD``; ``+ -``;
  ``EQ NE GT GE LT LE``; ``AND OR XOR``; left to right within a level;
* ``O`` words: ``O<name>|O123`` followed by ``sub endsub return call do while endwhile if elseif else
  endif break continue repeat endrepeat`` and their bracketed arguments, or nothing (a Fanuc style
  program number, which is ignored).

Errors are :class:`fusioncut.errors.InputError` naming ``file:line:column`` (1-based column in the
original text).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from typing import Callable, Protocol

from fusioncut.errors import InputError, SourceLocation

# Two numbers compare equal in EQ/NE when they differ by less than this (LinuxCNC's TOLERANCE_EQUAL).
EQ_TOLERANCE = 1e-6
# Numbered parameters LinuxCNC knows (RS274NGC_MAX_PARAMETERS - 1).
MAX_PARAMETER = 5601


class ParameterStore(Protocol):
    """What compiled expressions need from the interpreter (values in program units)."""

    def get_numbered(self, index: int, where: SourceLocation) -> float: ...

    def get_named(self, name: str, where: SourceLocation) -> float: ...

    def has_named(self, name: str) -> bool: ...


Value = float | Callable[[ParameterStore], float]
"""A word's value: a float when constant, else a closure evaluated against the parameters."""


@dataclass(slots=True)
class ParamRef:
    """Target of a parameter setting ``#... = value``: a number, a name, or an expression giving the number."""

    number: int | None = None
    name: str | None = None
    index: Value | None = None


@dataclass(slots=True)
class OWord:
    """An O-word control line: ``label`` is ``"123"`` or ``"<name>"`` lower-cased; ``keyword`` is
    ``""`` for a bare program number."""

    label: str
    keyword: str
    args: list[Value] = field(default_factory=list)
    column: int = 1


@dataclass(slots=True)
class Block:
    """One source line after reading. Column numbers are 1-based in the original text.

    ``g`` and ``m`` hold every G and M word (there may be several), ``words`` every other letter
    (at most one each, as in LinuxCNC). ``assignments`` are the parameter settings of the line, which
    take effect after the whole line was evaluated.
    """

    line: int
    text: str
    deleted: bool = False
    percent: bool = False  # the line starts with "%"
    percent_text: str = ""  # what follows that "%" (stripped); a program delimiter has none
    g: list[tuple[Value, int]] = field(default_factory=list)
    m: list[tuple[Value, int]] = field(default_factory=list)
    words: dict[str, tuple[Value, int]] = field(default_factory=dict)
    assignments: list[tuple[ParamRef, Value, int]] = field(default_factory=list)
    comment: str | None = None
    comment_column: int = 0
    oword: OWord | None = None
    constant: bool = True  # every value is a plain float
    simple: bool = False  # only N, X, Y, Z, F words with plain numbers, no comment

    @property
    def standalone_comment(self) -> bool:
        """True for a line holding only a comment (and maybe an ``N`` number)."""
        return (
            self.comment is not None
            and not self.g
            and not self.m
            and not (set(self.words) - {"n"})
            and not self.assignments
            and self.oword is None
        )

    @property
    def is_empty(self) -> bool:
        return not self.g and not self.m and not self.words and not self.assignments and self.oword is None


# ---------------------------------------------------------------------------------------------
# fast path: most lines of posted programs are letters and plain numbers with at most a trailing
# comment; a regex reads them ~10x faster than the general scanner.

_NUM = r"[-+]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)"
_FAST_LINE = re.compile(
    r"[ \t]*(?:[A-NP-Za-np-z][ \t]*" + _NUM + r"[ \t]*)*(?:\([^()]*\)[ \t]*)*(?:;.*)?\Z", re.S
)
_FAST_WORD = re.compile(r"([A-Za-z])[ \t]*(" + _NUM + r")")
_COMMENT_RE = re.compile(r"\(([^()]*)\)|;(.*)", re.S)
# Literal numbers beyond this are refused: no machine coordinate, feed or code is this large, and
# keeping every value finite keeps the arithmetic downstream free of overflow.
MAX_LITERAL = 1e12
# Limits that keep pathological expressions from exhausting Python's recursion
MAX_NESTING = 60
MAX_OPERATIONS = 200

_LETTERS = frozenset("abcdefghijklmnpqrstuvwxyz")  # O is handled on its own
_DIGITS = "0123456789"
_LOWER = {c: c.lower() for c in "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz"}
# blocks with only these words (and plain numbers) take the interpreter's fast path
_SIMPLE_WORDS = frozenset("nxyzf")


def parse_line(text: str, line: int, file: str) -> Block:
    """Read one source line (without its newline) into a :class:`Block`."""
    block = Block(line=line, text=text)
    s = text.strip()
    if not s:
        return block
    if s[0] == "%":
        # a "%" alone is a program delimiter (LinuxCNC); the interpreter decides what text after it means
        block.percent = True
        block.percent_text = s[1:].strip()
        return block
    body = text
    offset = 0
    stripped = body.lstrip()
    if stripped.startswith("/"):
        block.deleted = True
        offset = len(body) - len(stripped) + 1
        body = body[offset:]
    if _FAST_LINE.match(body):
        _parse_fast(block, body, offset, file)
    else:
        _Scanner(block, body, offset, file).parse()
    return block


def _parse_fast(block: Block, body: str, offset: int, file: str) -> None:
    # _FAST_LINE guarantees that comments only follow the words; the last one is the block's
    cut = len(body)
    for m in _COMMENT_RE.finditer(body):
        if cut == len(body):
            cut = m.start()
        block.comment = m.group(1) if m.group(1) is not None else m.group(2).strip()
        block.comment_column = offset + m.start() + 1
    first = True
    words = block.words
    for m in _FAST_WORD.finditer(body, 0, cut):
        letter, number = m.groups()
        letter = _LOWER[letter]
        col = offset + m.start(1) + 1
        if len(number) > 14 and abs(float(number)) > MAX_LITERAL:
            raise InputError(f"number {number[:20]}... too large", SourceLocation(file, block.line, col))
        if letter == "g":
            block.g.append((float(number), col))
        elif letter == "m":
            block.m.append((float(number), col))
        elif letter in words or (letter == "n" and not first):
            _add_word(block, letter, float(number), col, first, file)  # raises the error
        else:
            words[letter] = (float(number), col)
        first = False
    block.simple = not block.g and not block.m and block.comment is None and words.keys() <= _SIMPLE_WORDS


def _add_word(block: Block, letter: str, value: Value, col: int, first: bool, file: str) -> None:
    if letter == "g":
        block.g.append((value, col))
    elif letter == "m":
        block.m.append((value, col))
    elif letter == "n":
        if not first:
            raise InputError("N line number must come first on the line", SourceLocation(file, block.line, col))
        block.words["n"] = (value, col)
    else:
        if letter in block.words:
            raise InputError(f"more than one {letter.upper()} word on the line", SourceLocation(file, block.line, col))
        block.words[letter] = (value, col)


# ---------------------------------------------------------------------------------------------
# general scanner


_UNARY = frozenset(
    ("abs", "acos", "asin", "atan", "cos", "exp", "fix", "fup", "ln", "round", "sin", "sqrt", "tan", "exists")
)
_NUM_RE = re.compile(_NUM)
_NAME_RE = re.compile(r"[a-z]+")
_BINARY_WORDS = ("mod", "and", "xor", "or", "eq", "ne", "gt", "ge", "lt", "le")
_PRECEDENCE = {
    "**": 4,
    "*": 3,
    "/": 3,
    "mod": 3,
    "+": 2,
    "-": 2,
    "eq": 1,
    "ne": 1,
    "gt": 1,
    "ge": 1,
    "lt": 1,
    "le": 1,
    "and": 0,
    "or": 0,
    "xor": 0,
}
_OWORD_KEYWORDS = (
    "endsub",
    "endwhile",
    "endif",
    "endrepeat",
    "elseif",
    "else",
    "sub",
    "return",
    "call",
    "do",
    "while",
    "if",
    "break",
    "continue",
    "repeat",
)


class _Scanner:
    """Character scanner over a line with comments and white space removed, remembering columns."""

    def __init__(self, block: Block, body: str, offset: int, file: str):
        self.block = block
        self.file = file
        chars: list[str] = []
        cols: list[int] = []
        i, n = 0, len(body)
        while i < n:
            ch = body[i]
            if ch == "(":
                j = body.find(")", i + 1)
                if j < 0:
                    raise self._err_at("comment opened with '(' is not closed", offset + i + 1)
                inner = body[i + 1 : j]
                if "(" in inner:
                    raise self._err_at("nested comment", offset + i + 1)
                block.comment = inner
                block.comment_column = offset + i + 1
                i = j + 1
                continue
            if ch == ";":
                block.comment = body[i + 1 :].strip()
                block.comment_column = offset + i + 1
                break
            if ch == ")":
                raise self._err_at("')' without an opening '('", offset + i + 1)
            if not ch.isspace():
                chars.append(ch.lower())
                cols.append(offset + i + 1)
            i += 1
        self.s = "".join(chars)
        self.cols = cols
        self.pos = 0
        self.end_col = offset + len(body) + 1
        self.depth = 0
        self.operations = 0

    # -- helpers
    def _col(self, pos: int | None = None) -> int:
        p = self.pos if pos is None else pos
        return self.cols[p] if p < len(self.cols) else self.end_col

    def _err_at(self, msg: str, col: int) -> InputError:
        return InputError(msg, SourceLocation(self.file, self.block.line, col))

    def err(self, msg: str, pos: int | None = None) -> InputError:
        return self._err_at(msg, self._col(pos))

    def peek(self, k: int = 0) -> str:
        p = self.pos + k
        return self.s[p] if p < len(self.s) else ""

    def startswith(self, word: str) -> bool:
        return self.s.startswith(word, self.pos)

    # -- line
    def parse(self) -> None:
        b = self.block
        s = self.s
        first = True
        if s.startswith("o"):
            self.parse_oword()
            return
        while self.pos < len(s):
            ch = s[self.pos]
            col = self._col()
            if ch == "#":
                self.parse_assignment()
            elif ch in _LETTERS:
                self.pos += 1
                value = self.real_value()
                _add_word(b, ch, value, col, first, self.file)
            elif ch == "o":
                raise self.err("an O word must start its line")
            else:
                raise self.err(f"unexpected character {ch!r}")
            first = False

    def parse_assignment(self) -> None:
        col = self._col()
        self.pos += 1  # '#'
        ref = self.param_ref()
        if self.peek() != "=":
            raise self.err("expected '=' after a parameter at the start of a word (parameter setting)")
        self.pos += 1
        value = self.real_value()
        self.block.assignments.append((ref, value, col))

    def param_ref(self) -> ParamRef:
        """After a '#': the parameter's number, name or index expression."""
        ch = self.peek()
        if ch == "<":
            end = self.s.find(">", self.pos)
            if end < 0:
                raise self.err("named parameter without a closing '>'")
            name = self.s[self.pos + 1 : end]
            if not name:
                raise self.err("empty parameter name")
            self.pos = end + 1
            return ParamRef(name=name)
        if _isdigit(ch):
            start = self.pos
            while _isdigit(self.peek()):
                self.pos += 1
            if self.peek() == ".":
                raise self.err("parameter number must be an integer", start)
            if self.pos - start > 6:
                raise self.err("parameter number out of range", start)
            number = int(self.s[start : self.pos])
            if not 1 <= number <= MAX_PARAMETER:
                raise self.err(f"parameter number {number} out of range 1..{MAX_PARAMETER}", start)
            return ParamRef(number=number)
        if ch in "#[":
            self.block.constant = False
            return ParamRef(index=self.real_value())
        raise self.err("expected a parameter number, <name> or [expression] after '#'")

    # -- values
    def real_value(self) -> Value:
        self.depth += 1
        try:
            return self._real_value()
        finally:
            self.depth -= 1

    def _real_value(self) -> Value:
        if self.depth > MAX_NESTING:
            raise self.err(f"value nested more than {MAX_NESTING} deep")
        ch = self.peek()
        col = self._col()
        if ch == "":
            raise self.err("value missing at the end of the line")
        if ch == "[":
            self.pos += 1
            v = self.expression()
            return v
        if ch == "#":
            self.block.constant = False
            self.pos += 1
            return self._param_value(self.param_ref(), col)
        if ch in "+-":
            self.pos += 1
            nxt = self.peek()
            if _isdigit(nxt) or nxt == ".":
                self.pos -= 1
                return self.number()
            inner = self.real_value()
            if ch == "+":
                return inner
            return _negate(inner)
        if _isdigit(ch) or ch == ".":
            return self.number()
        if ch in _LETTERS or ch == "o":
            return self.unary_function()
        raise self.err(f"expected a number, [expression], #parameter or function, got {ch!r}")

    def number(self) -> float:
        m = _NUM_RE.match(self.s, self.pos)
        if not m:
            raise self.err("bad number")
        start = self.pos
        self.pos = m.end()
        if self.peek() == ".":
            raise self.err("bad number (two decimal points)")
        v = float(m.group(0))
        if abs(v) > MAX_LITERAL:
            raise self.err(f"number {m.group(0)[:20]} too large", start)
        return v

    def _param_value(self, ref: ParamRef, col: int) -> Value:
        file, line = self.file, self.block.line
        where = SourceLocation(file, line, col)
        if ref.name is not None:
            name = ref.name
            return lambda p: p.get_named(name, where)
        if ref.number is not None:
            number = ref.number
            return lambda p: p.get_numbered(number, where)
        index = ref.index
        assert index is not None

        def indirect(p: ParameterStore) -> float:
            return p.get_numbered(param_index(evaluate(index, p), where), where)

        return indirect

    def unary_function(self) -> Value:
        start = self.pos
        m = _NAME_RE.match(self.s, self.pos)
        if m is None:
            raise self.err(f"unexpected character {self.s[self.pos]!r}")
        name = m.group(0)
        # the name is followed by '[' so a greedy match may have swallowed nothing else
        if name not in _UNARY:
            raise self.err(f"unknown function or word {name.upper()!r}", start)
        self.pos = m.end()
        col = self._col(start)
        where = SourceLocation(self.file, self.block.line, col)
        if self.peek() != "[":
            raise self.err(f"{name.upper()} needs its argument in [brackets]")
        self.block.constant = False
        if name == "exists":
            self.pos += 1
            if not self.startswith("#<"):
                raise self.err("EXISTS needs a named parameter: EXISTS[#<name>]")
            self.pos += 1
            ref = self.param_ref()
            if self.peek() != "]":
                raise self.err("expected ']' after EXISTS[#<name>")
            self.pos += 1
            pname = ref.name
            return lambda p: 1.0 if p.has_named(pname) else 0.0  # type: ignore[arg-type]
        self.pos += 1
        arg = self.expression()
        if name == "atan":
            if not (self.peek() == "/" and self.peek(1) == "["):
                raise self.err("ATAN takes two arguments: ATAN[y]/[x]")
            self.pos += 2
            arg2 = self.expression()
            return lambda p: math.degrees(math.atan2(evaluate(arg, p), evaluate(arg2, p)))
        return _unary(name, arg, where)

    def expression(self) -> Value:
        """Reads up to and including the closing ']' (the '[' is already consumed)."""
        operands: list[Value] = [self.expr_operand()]
        operators: list[tuple[str, int]] = []
        while True:
            ch = self.peek()
            if ch == "]":
                self.pos += 1
                break
            if ch == "":
                raise self.err("expression not closed with ']'")
            col = self._col()
            op = self.binary_operator()
            self.operations += 1
            if self.operations > MAX_OPERATIONS:
                raise self.err(f"more than {MAX_OPERATIONS} operations on one line")
            while operators and _PRECEDENCE[operators[-1][0]] >= _PRECEDENCE[op]:
                _reduce(operands, operators, self.file, self.block.line)
            operators.append((op, col))
            operands.append(self.expr_operand())
        while operators:
            _reduce(operands, operators, self.file, self.block.line)
        return operands[0]

    def expr_operand(self) -> Value:
        ch = self.peek()
        if ch == "-" or ch == "+":
            # unary sign inside an expression, e.g. [-#1] or [-SIN[30]]
            self.pos += 1
            self.depth += 1
            if self.depth > MAX_NESTING:
                raise self.err(f"value nested more than {MAX_NESTING} deep")
            try:
                inner = self.expr_operand()
            finally:
                self.depth -= 1
            if ch == "+":
                return inner
            return _negate(inner)
        return self.real_value()

    def binary_operator(self) -> str:
        ch = self.peek()
        if ch == "*":
            if self.peek(1) == "*":
                self.pos += 2
                return "**"
            self.pos += 1
            return "*"
        if ch in "/+-":
            self.pos += 1
            return ch
        for w in _BINARY_WORDS:
            if self.startswith(w):
                self.pos += len(w)
                return w
        raise self.err("expected a binary operator or ']'")

    # -- O words
    def parse_oword(self) -> None:
        col = self._col()
        self.pos = 1
        if self.peek() == "<":
            end = self.s.find(">", self.pos)
            if end < 0:
                raise self.err("O-word name without a closing '>'")
            label = self.s[self.pos : end + 1]
            self.pos = end + 1
        elif _isdigit(self.peek()):
            start = self.pos
            while _isdigit(self.peek()):
                self.pos += 1
            if self.pos - start > 9:
                raise self.err("O-word number too long", start)
            label = str(int(self.s[start : self.pos]))
        elif self.peek() in "[#":
            raise self.err("computed O-word labels are not supported")
        else:
            raise self.err("O word needs a number or <name>")
        keyword = ""
        for kw in _OWORD_KEYWORDS:
            if self.startswith(kw):
                keyword = kw
                self.pos += len(kw)
                break
        ow = OWord(label=label, keyword=keyword, column=col)
        if keyword in ("call", "repeat", "while", "if", "elseif", "return", "endsub"):
            while self.peek() == "[":
                self.pos += 1
                ow.args.append(self.expression())
            self.block.constant = False
        if self.pos < len(self.s):
            if keyword == "":
                raise self.err("unknown O-word keyword")
            raise self.err(f"unexpected text after O-word {keyword!r}")
        if keyword in ("while", "if", "elseif", "repeat") and len(ow.args) != 1:
            raise self._err_at(f"O-word {keyword} needs one [condition]", col)
        self.block.oword = ow


def _negate(v: Value) -> Value:
    if isinstance(v, float):
        return -v
    f = v

    def neg(p: ParameterStore) -> float:
        return -f(p)

    return neg


def _isdigit(ch: str) -> bool:
    """ASCII digit test (str.isdigit() also accepts digits int() and float() may refuse)."""
    return ch != "" and ch in _DIGITS


def param_index(v: float, where: SourceLocation) -> int:
    """The parameter number a computed index ``v`` names (within 1e-4 of a whole number, 1..5601)."""
    n = round(v)
    if abs(v - n) > 1e-4:
        raise InputError(f"parameter number {v:g} is not an integer", where)
    if not 1 <= n <= MAX_PARAMETER:
        raise InputError(f"parameter number {n} out of range 1..{MAX_PARAMETER}", where)
    return int(n)


def evaluate(v: Value, params: ParameterStore) -> float:
    return v if isinstance(v, float) else v(params)


def _check(x: float, where: SourceLocation, what: str) -> float:
    if math.isnan(x) or math.isinf(x):
        raise InputError(f"{what} gives a non-finite result", where)
    return x


def _unary(name: str, arg: Value, where: SourceLocation) -> Value:
    def f(p: ParameterStore) -> float:
        x = evaluate(arg, p)
        if name == "abs":
            return abs(x)
        if name == "acos":
            if not -1.0 <= x <= 1.0:
                raise InputError(f"ACOS argument {x:g} outside [-1, 1]", where)
            return math.degrees(math.acos(x))
        if name == "asin":
            if not -1.0 <= x <= 1.0:
                raise InputError(f"ASIN argument {x:g} outside [-1, 1]", where)
            return math.degrees(math.asin(x))
        if name == "cos":
            return math.cos(math.radians(x))
        if name == "sin":
            return math.sin(math.radians(x))
        if name == "tan":
            return _check(math.tan(math.radians(x)), where, "TAN")
        if name == "exp":
            try:
                return math.exp(x)
            except OverflowError:
                raise InputError(f"EXP[{x:g}] overflows", where) from None
        if name == "ln":
            if x <= 0:
                raise InputError(f"LN argument {x:g} must be > 0", where)
            return math.log(x)
        if name == "sqrt":
            if x < 0:
                raise InputError(f"SQRT argument {x:g} must be >= 0", where)
            return math.sqrt(x)
        if not math.isfinite(x):
            raise InputError(f"{name.upper()} of a non-finite value", where)
        if name == "fix":
            return float(math.floor(x))
        if name == "fup":
            return float(math.ceil(x))
        if name == "round":
            # half away from zero, as LinuxCNC does (Python's round() rounds half to even)
            return float(math.floor(x + 0.5)) if x >= 0 else -float(math.floor(-x + 0.5))
        raise AssertionError(name)

    return f


def _reduce(operands: list[Value], operators: list[tuple[str, int]], file: str, line: int) -> None:
    op, col = operators.pop()
    right = operands.pop()
    left = operands.pop()
    operands.append(_binary(op, left, right, SourceLocation(file, line, col)))


def _binary(op: str, left: Value, right: Value, where: SourceLocation) -> Value:
    def f(p: ParameterStore) -> float:
        a = evaluate(left, p)
        b = evaluate(right, p)
        return _apply(op, a, b, where)

    if isinstance(left, float) and isinstance(right, float):
        # constant folding keeps pure-number expressions as cheap as literals
        return _apply(op, left, right, where)
    return f


def _apply(op: str, a: float, b: float, where: SourceLocation) -> float:
    if op == "+":
        r = a + b
    elif op == "-":
        r = a - b
    elif op == "*":
        r = a * b
    elif op == "/":
        if b == 0.0:
            raise InputError("division by zero", where)
        r = a / b
    elif op == "mod":
        if b == 0.0:
            raise InputError("MOD by zero", where)
        r = math.fmod(a, b)
        if r < 0.0:
            r += abs(b)  # LinuxCNC keeps the result non-negative
    elif op == "**":
        if a < 0.0 and b != math.floor(b):
            raise InputError("negative number raised to a non-integer power", where)
        if a == 0.0 and b < 0.0:
            raise InputError("zero raised to a negative power", where)
        try:
            r = math.pow(a, b)
        except OverflowError:
            raise InputError("power overflows", where) from None
    elif op == "eq":
        r = 1.0 if abs(a - b) < EQ_TOLERANCE else 0.0
    elif op == "ne":
        r = 0.0 if abs(a - b) < EQ_TOLERANCE else 1.0
    elif op == "gt":
        r = 1.0 if a > b else 0.0
    elif op == "ge":
        r = 1.0 if a >= b else 0.0
    elif op == "lt":
        r = 1.0 if a < b else 0.0
    elif op == "le":
        r = 1.0 if a <= b else 0.0
    elif op == "and":
        r = 1.0 if (a != 0.0 and b != 0.0) else 0.0
    elif op == "or":
        r = 1.0 if (a != 0.0 or b != 0.0) else 0.0
    elif op == "xor":
        r = 1.0 if ((a != 0.0) != (b != 0.0)) else 0.0
    else:  # pragma: no cover - the scanner only produces the operators above
        raise AssertionError(op)
    return _check(r, where, f"operator {op.upper()}")
