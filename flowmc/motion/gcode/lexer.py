"""One line of RS274/NGC text into a ``Block``: words, parameter settings, an O-word, the last comment.

LinuxCNC's reading rules (the G-code overview is the reference): spaces and tabs mean nothing outside
comments, case means nothing outside comments, ``( )`` comments do not nest, ``;`` comments run to
the end of the line, ``/`` first on a line marks block delete, ``N`` (with an optional ``.digits``)
may only come first, ``O`` words only start a line. A value is a number, ``[expression]``,
``#parameter`` or a unary function (``SIN[30]``, ``ATAN[1]/[2]``), with an optional sign.

Values are floats, or expression nodes (tuples, see ``expr``) when they read parameters; constant
sub-expressions are folded here, so a line without parameters carries plain floats. Nothing here
evaluates a parameter or runs code: the parse only builds data.
"""

from __future__ import annotations

import re

import flowmc.motion.gcode.expr as X

__all__ = ["Block", "LexError", "parse_line", "split_comments"]


class LexError(Exception):
    """A line that does not read; the interpreter adds the file and line."""


class Block:
    """A parsed line. ``words`` maps single letters to values; ``g``/``m`` list the G and M values in
    order; ``assign`` the parameter settings (target, value); ``oword`` is (label, keyword, args)."""

    __slots__ = ("words", "g", "m", "assign", "comment", "oword", "delete", "const", "run")

    def __init__(self):
        self.words: dict = {}
        self.g: list = []
        self.m: list = []
        self.assign: list = []
        self.comment: str | None = None
        self.oword: tuple | None = None
        self.delete = False
        self.const = True  # every value is a plain float (no parameter reads)
        self.run = None  # once compiled: codegen.compile_block's function, or a call's argument values (value_list)


_NUMBER = re.compile(r"\d+\.?\d*|\.\d+")
_LINE_NUMBER = re.compile(r"N\d+(?:\.\d*)?")
_SIMPLE = re.compile(r"(?:[A-Z][-+]?(?:\d+\.?\d*|\.\d+))+")
_WORD = re.compile(r"([A-Z])([-+]?(?:\d+\.?\d*|\.\d+))")
_FUNCTION = re.compile(r"(ABS|ACOS|ASIN|ATAN|COS|EXISTS|EXP|FIX|FUP|LN|ROUND|SIN|SQRT|TAN)\[")
_OPERATOR_WORD = re.compile(r"MOD|AND|XOR|OR|EQ|NE|GT|GE|LT|LE")
_OWORD_KEY = re.compile(r"ENDSUB|SUB|CALL|RETURN|DO|WHILE|ENDWHILE|IF|ELSEIF|ELSE|ENDIF|BREAK|CONTINUE|"
                        r"REPEAT|ENDREPEAT")
_COMMENT = re.compile(r"\(([^()]*)\)")


def squeeze(code: str) -> str:
    """Code without spaces or tabs, upper-cased (``str.replace`` is several times faster than
    ``str.translate`` here)."""
    code = code.replace(" ", "")
    if "\t" in code:
        code = code.replace("\t", "")
    return code.upper()


# Binary operators: text -> (precedence, opcode).
_OPS = {"**": (5, X.POW), "*": (4, X.MUL), "/": (4, X.DIV), "MOD": (4, X.MOD), "+": (3, X.ADD), "-": (3, X.SUB),
        "EQ": (2, X.EQ), "NE": (2, X.NE), "GT": (2, X.GT), "GE": (2, X.GE), "LT": (2, X.LT), "LE": (2, X.LE),
        "AND": (1, X.AND), "OR": (1, X.OR), "XOR": (1, X.XOR)}
_AXIS_HINT = {c: f"axis {c} is not supported (flowmc paths have X, Y and Z)" for c in "ABCUVW"}


def split_comments(raw: str) -> tuple[str, str | None]:
    """(code without comments, spaces or tabs, upper-cased; the last comment's text or None)."""
    if "(" not in raw and ";" not in raw and ")" not in raw:
        return squeeze(raw), None
    parts = []
    comment = None
    pos = 0
    n = len(raw)
    while pos < n:
        open_at = raw.find("(", pos)
        semi = raw.find(";", pos)
        close_at = raw.find(")", pos)
        stops = [k for k in (open_at, semi, close_at) if k >= 0]
        if not stops:
            parts.append(raw[pos:])
            break
        k = min(stops)
        parts.append(raw[pos:k])
        if k == close_at:
            raise LexError("')' without a '(' before it")
        if k == semi:
            comment = raw[k + 1:]
            break
        end = raw.find(")", k + 1)
        nested = raw.find("(", k + 1)
        if end < 0:
            raise LexError("comment is not closed: ')' is missing")
        if 0 <= nested < end:
            raise LexError("comments do not nest: '(' inside a comment")
        comment = raw[k + 1:end]
        pos = end + 1
    return squeeze("".join(parts)), comment


def parse_line(code: str) -> Block:
    """Parse a cleaned line (``split_comments``'s code) into a Block."""
    block = Block()
    i = 0
    n = len(code)
    if n and code[0] == "/":
        block.delete = True
        i = 1
    if i < n and code[i] == "N":
        m = _LINE_NUMBER.match(code, i)
        if m is None:
            raise LexError("N (line number) must be followed by a whole number")
        i = m.end()
    if i >= n:
        return block
    if code[i] == "O":
        _parse_oword(code, i, block)
        return block
    rest = code[i:] if i else code
    if _SIMPLE.fullmatch(rest) and "N" not in rest and "O" not in rest:
        words = block.words
        for letter, number in _WORD.findall(rest):
            _add_word(block, words, letter, float(number))
        return block
    try:
        return _parse_tokens(code, i, block)
    except (_Fallback, IndexError, KeyError, ValueError):
        block = Block()
        block.delete = code[:1] == "/"
    return _parse_chars(code, i, block)


def _parse_chars(code: str, i: int, block: Block) -> Block:
    """Character by character, as LinuxCNC reads: slower than the token parser, and the one that
    explains what is wrong with a line."""
    n = len(code)
    words = block.words
    while i < n:
        c = code[i]
        if c == "#":
            target, i = _read_target(code, i)
            if i >= n or code[i] != "=":
                raise LexError("a parameter on its own must be set: '=' is missing after it")
            value, i = _read_value(code, i + 1)
            if type(value) is not float or type(target) is tuple:
                block.const = False
            block.assign.append((target, value))
            continue
        if "A" <= c <= "Z" or c == "@" or c == "^":
            if c == "N":
                raise LexError("an N word (line number) must come first on its line")
            if c == "O":
                raise LexError("an O-word must start its line (nothing may come before it)")
            if i + 1 >= n:
                raise LexError(f"{c} word has no number after it")
            value, i = _read_value(code, i + 1, c)
            if type(value) is not float:
                block.const = False
            _add_word(block, words, c, value)
            continue
        raise LexError(_unexpected(code, i))
    return block


class _Fallback(Exception):
    """The token parser met something it leaves to the character parser."""


_TOKEN = re.compile(r"\d+\.?\d*|\.\d+|\*\*|<[^>]*>|[A-Z]+|[^\dA-Z]")
_FUNCTIONS = frozenset(("ABS", "ACOS", "ASIN", "ATAN", "COS", "EXISTS", "EXP", "FIX", "FUP", "LN", "ROUND", "SIN",
                        "SQRT", "TAN"))
_OPERATOR_WORDS = ("MOD", "AND", "XOR", "OR", "EQ", "NE", "GT", "GE", "LT", "LE")
_WORD_LETTERS = frozenset("ABCDEFGHIJKLMPQRSTUVWXYZ@^")


def _parse_tokens(code: str, i: int, block: Block) -> Block:
    """The fast way through a line with expressions: one regex split into tokens, then precedence
    climbing over the token list. Anything unusual is left to ``_parse_chars`` (raise _Fallback)."""
    toks = _TOKEN.findall(code, i)
    n = len(toks)
    k = 0
    words = block.words
    const = True
    while k < n:
        t = toks[k]
        if t == "#":
            if k + 1 < n and toks[k + 1][0] == "<":
                target = toks[k + 1][1:-1].lower()
                if not target:
                    raise _Fallback
                k += 2
            else:
                index, k = _tvalue(toks, k + 1)
                if type(index) is float:
                    target = X.param_index(index)
                else:
                    target = (X.INDEX, index)
                    const = False
            if toks[k] != "=":
                raise _Fallback
            value, k = _tvalue(toks, k + 1)
            if type(value) is not float:
                const = False
            block.assign.append((target, value))
            continue
        first = t[0]
        if first not in _WORD_LETTERS:
            raise _Fallback
        if len(t) > 1:
            if t[1:] not in _FUNCTIONS or first in "A":
                raise _Fallback  # e.g. ACOS[..] after an A word: the character parser decides
            toks[k] = t[1:]
            value, k = _tvalue(toks, k)
        else:
            value, k = _tvalue(toks, k + 1)
        if type(value) is not float:
            const = False
        if first == "G":
            block.g.append(value)
        elif first == "M":
            block.m.append(value)
        elif first in words:
            raise _Fallback
        else:
            words[first] = value
    block.const = const
    return block


def _tvalue(toks: list, k: int):
    """A value starting at token k: (value, next k)."""
    t = toks[k]
    c = t[0]
    if "0" <= c <= "9" or c == ".":
        return float(t), k + 1
    if t == "[":
        return _texpression(toks, k)
    if t == "#":
        nxt = toks[k + 1]
        if nxt[0] == "<":
            name = nxt[1:-1].lower()
            if not name:
                raise _Fallback
            return (X.NAMED, name), k + 2
        index, k = _tvalue(toks, k + 1)
        return ((X.PARAM, X.param_index(index)) if type(index) is float else (X.PARAM, index)), k
    if t == "-" or t == "+":
        if toks[k + 1] in ("-", "+"):
            raise _Fallback
        value, k = _tvalue(toks, k + 1)
        if t == "+":
            return value, k
        return (-value if type(value) is float else (X.NEG, value)), k
    if t in _FUNCTIONS:
        if toks[k + 1] != "[":
            raise _Fallback
        arg, k = _texpression(toks, k + 1)
        if t == "EXISTS":
            if not (isinstance(arg, tuple) and arg[0] == X.NAMED):
                raise _Fallback
            return (X.EXISTS, arg[1]), k
        if t == "ATAN":
            if toks[k] != "/" or toks[k + 1] != "[":
                raise _Fallback
            arg2, k = _texpression(toks, k + 1)
            return X.fold_atan(arg, arg2), k
        return X.fold_function(t, arg), k
    raise _Fallback


def _texpression(toks: list, k: int):
    """``[ ... ]`` from token k ('['): operators by precedence, left to right within a level."""
    value, k = _tvalue(toks, k + 1)
    t = toks[k]
    if t == "]":
        return value, k + 1
    values = [value]
    ops: list = []
    fold = X.fold_binary
    while t != "]":
        entry = _OPS.get(t)
        if entry is None:
            if t[0] < "A" or t[0] > "Z":
                raise _Fallback
            # An operator word run together with a function after it (e.g. "ANDSIN").
            for word in _OPERATOR_WORDS:
                if t.startswith(word) and t[len(word):] in _FUNCTIONS:
                    entry = _OPS[word]
                    toks[k] = t[len(word):]
                    k -= 1
                    break
            else:
                raise _Fallback
        prec = entry[0]
        while ops and ops[-1][0] >= prec:
            op = ops.pop()[1]
            rhs = values.pop()
            values[-1] = fold(op, values[-1], rhs)
        ops.append(entry)
        value, k = _tvalue(toks, k + 1)
        values.append(value)
        t = toks[k]
    while ops:
        op = ops.pop()[1]
        rhs = values.pop()
        values[-1] = fold(op, values[-1], rhs)
    return values[0], k + 1


def _add_word(block: Block, words: dict, letter: str, value) -> None:
    if letter == "G":
        block.g.append(value)
    elif letter == "M":
        block.m.append(value)
    elif letter in words:
        raise LexError(f"two {letter} words on one line")
    else:
        words[letter] = value


def _unexpected(code: str, i: int) -> str:
    c = code[i]
    if c == "%":
        return "'%' may only open and close the program, on a line of its own"
    if c.isdigit() or c in ".+-":
        return f"number {_number_at(code, i)!r} has no letter before it"
    if c in "[]":
        return "an expression ([ ]) must be the value of a word or a parameter setting"
    if c == "=":
        return "'=' without a parameter before it"
    if c.isprintable() and c.isascii():
        return f"unexpected character {c!r}"
    return f"unexpected character {ascii(c)}"


def _number_at(code: str, i: int) -> str:
    j = i
    while j < len(code) and (code[j].isdigit() or code[j] in ".+-"):
        j += 1
    return code[i:j]


def _read_target(code: str, i: int):
    """``#n`` or ``#<name>`` on the left of '=': (int index | name str | node, next index)."""
    if i + 1 < len(code) and code[i + 1] == "<":
        name, i = _read_name(code, i + 1)
        return name, i
    index, i = _read_value(code, i + 1, "#")
    if type(index) is float:
        return X.param_index(index), i
    return (X.INDEX, index), i


def _read_name(code: str, i: int) -> tuple[str, int]:
    end = code.find(">", i)
    if end < 0:
        raise LexError("named parameter is not closed: '>' is missing")
    name = code[i + 1:end].lower()
    if not name:
        raise LexError("named parameter has an empty name")
    return name, end + 1


def _read_value(code: str, i: int, letter: str = ""):
    """A real value at ``code[i]``: number, [expression], #parameter, function, with optional sign."""
    n = len(code)
    if i >= n:
        raise LexError(f"{letter} word has no number after it" if letter else "a value is missing")
    c = code[i]
    if c == "[":
        return _read_expression(code, i)
    if c == "]":
        raise LexError("a value is missing before ']'")
    if c == "#":
        if i + 1 < n and code[i + 1] == "<":
            name, j = _read_name(code, i + 1)
            return (X.NAMED, name), j
        index, j = _read_value(code, i + 1, "#")
        if type(index) is float:
            return (X.PARAM, X.param_index(index)), j
        return (X.PARAM, index), j
    if c == "-" or c == "+":
        if i + 1 < n and code[i + 1] in "-+":
            raise LexError(f"malformed number after {letter}: two signs" if letter else "two signs in a row")
        value, j = _read_value(code, i + 1, letter)
        if c == "+":
            return value, j
        return (-value if type(value) is float else (X.NEG, value)), j
    if "A" <= c <= "Z":
        m = _FUNCTION.match(code, i)
        if m is None:
            if letter and letter != "#":
                after = code[i:i + 1]
                raise LexError(f"{letter} word has no number after it" if after not in _AXIS_HINT
                               else f"{letter} word has no number after it")
            raise LexError(f"unknown function or operator at {code[i:i + 8]!r}")
        name = m.group(1)
        arg, j = _read_expression(code, m.end() - 1)
        if name == "EXISTS":
            if not (isinstance(arg, tuple) and arg[0] == X.NAMED):
                raise LexError("EXISTS takes one named parameter: EXISTS[#<name>]")
            return (X.EXISTS, arg[1]), j
        if name == "ATAN":
            if not code.startswith("/[", j):
                raise LexError("ATAN needs two arguments: ATAN[y]/[x]")
            arg2, j = _read_expression(code, j + 1)
            return X.fold_atan(arg, arg2), j
        return X.fold_function(name, arg), j
    m = _NUMBER.match(code, i)
    if m is None:
        if letter and letter != "#":
            raise LexError(f"{letter} word has no number after it" if c not in "[]" else
                           f"malformed value after {letter}")
        raise LexError(_unexpected(code, i))
    j = m.end()
    if j < n and code[j] == ".":
        raise LexError(f"malformed number after {letter}: {_number_at(code, i)!r}" if letter
                       else f"malformed number {_number_at(code, i)!r}")
    return float(m.group()), j


def _read_expression(code: str, i: int):
    """``[ ... ]`` starting at code[i] == '['."""
    value, i = _read_binary(code, i + 1, 1)
    if i >= len(code) or code[i] != "]":
        raise LexError("expression is not closed: ']' is missing" if i >= len(code)
                       else f"unexpected {code[i]!r} in an expression")
    return value, i + 1


def _peek_operator(code: str, i: int):
    if i >= len(code):
        return None, 0, i
    c = code[i]
    if c == "*":
        if code.startswith("**", i):
            return X.POW, 5, i + 2
        return X.MUL, 4, i + 1
    if c in "/+-":
        prec, op = _OPS[c]
        return op, prec, i + 1
    if "A" <= c <= "Z":
        m = _OPERATOR_WORD.match(code, i)
        if m is not None:
            prec, op = _OPS[m.group()]
            return op, prec, m.end()
        raise LexError(f"unknown operator at {code[i:i + 8]!r}")
    return None, 0, i


def _read_binary(code: str, i: int, min_prec: int):
    """Precedence climbing; operators of one precedence group associate to the left."""
    lhs, i = _read_value(code, i)
    while True:
        op, prec, j = _peek_operator(code, i)
        if op is None or prec < min_prec:
            return lhs, i
        rhs, i = _read_binary(code, j, prec + 1)
        lhs = X.fold_binary(op, lhs, rhs)


def _parse_oword(code: str, i: int, block: Block) -> None:
    """``O<label> keyword [args]``: label is a number, ``<name>``, or an expression giving a number."""
    i += 1
    if i < len(code) and code[i] == "<":
        label, i = _read_name(code, i)
    else:
        value, i = _read_value(code, i, "O")
        label = X.label_number(value) if type(value) is float else value
    m = _OWORD_KEY.match(code, i)
    if m is None:
        rest = code[i:i + 12]
        raise LexError(f"O-word without a known keyword (sub, endsub, call, return, if, elseif, else, endif, "
                       f"while, endwhile, do, break, continue, repeat, endrepeat){': ' + repr(rest) if rest else ''}")
    keyword = m.group().lower()
    i = m.end()
    args = []
    if i < len(code):
        try:
            toks = _TOKEN.findall(code, i)
            k = 0
            while k < len(toks):
                if toks[k] != "[" and keyword != "call":
                    raise _Fallback
                value, k = _tvalue(toks, k)
                args.append(value)
            i = len(code)
        except (_Fallback, IndexError, KeyError, ValueError):
            args = []
    while i < len(code):
        if code[i] != "[" and keyword != "call":
            raise LexError(f"unexpected {code[i:i + 8]!r} after 'o... {keyword}'")
        value, i = _read_value(code, i)
        if type(value) is not float:
            block.const = False
        args.append(value)
    if keyword in ("if", "elseif", "while", "repeat") and len(args) != 1:
        raise LexError(f"'{keyword}' needs one condition in brackets, e.g. o100 {keyword} [#1 LT 3]")
    if keyword in ("return", "endsub") and len(args) > 1:
        raise LexError(f"'{keyword}' takes at most one value")
    if keyword not in ("if", "elseif", "while", "repeat", "return", "endsub", "call") and args:
        raise LexError(f"'{keyword}' takes no value")
    if keyword == "call" and len(args) > 30:
        raise LexError("a subroutine takes at most 30 arguments")
    if type(label) is not str and type(label) is not int:
        block.const = False
    block.oword = (label, keyword, args)
