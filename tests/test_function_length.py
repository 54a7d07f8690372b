"""No function of the package is longer than :data:`MAX_LINES` lines of code.

A line of code is one that holds a token of code: blank lines, comment lines and docstrings do not
count, a statement continued over several lines counts each of them, and a function's nested
functions count towards it. Every module under ``src/cosserat_channel`` is read with ``ast`` and
``tokenize``; nothing is imported.
"""

from __future__ import annotations

import ast
import io
import tokenize
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parent.parent / "src" / "cosserat_channel"
MAX_LINES = 120
_NOT_CODE = {tokenize.COMMENT, tokenize.NL, tokenize.NEWLINE, tokenize.INDENT, tokenize.DEDENT,
             tokenize.ENCODING, tokenize.ENDMARKER}


def _docstring_lines(tree: ast.AST) -> set[int]:
    lines = set()
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            first = node.body[0] if node.body else None
            if (isinstance(first, ast.Expr) and isinstance(first.value, ast.Constant)
                    and isinstance(first.value.value, str)):
                lines.update(range(first.lineno, first.end_lineno + 1))
    return lines


def function_lengths(source: str) -> list[tuple[str, int, int]]:
    """``(name, first line, lines of code)`` of every function and method in ``source``."""
    tree = ast.parse(source)
    code = set()
    for tok in tokenize.generate_tokens(io.StringIO(source).readline):
        if tok.type not in _NOT_CODE:
            code.update(range(tok.start[0], tok.end[0] + 1))
    code -= _docstring_lines(tree)
    return [(node.name, node.lineno,
             sum(1 for line in range(node.lineno, node.end_lineno + 1) if line in code))
            for node in ast.walk(tree) if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef))]


def test_counts_code_lines_only():
    source = '''
def f(a,
      b):
    """A docstring

    over several lines."""
    # a comment

    x = (a +
         b)  # and a trailing one
    return x
'''
    assert function_lengths(source) == [("f", 2, 5)]


@pytest.mark.parametrize("path", sorted(SRC.rglob("*.py")), ids=lambda p: str(p.relative_to(SRC)))
def test_no_function_is_longer_than_the_limit(path):
    long = [f"{name} (line {line}): {n} lines" for name, line, n in
            function_lengths(path.read_text(encoding="utf-8")) if n > MAX_LINES]
    assert not long, f"over {MAX_LINES} lines of code in {path.relative_to(SRC)}: {long}"
