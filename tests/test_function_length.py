"""No function or method in ``toolkit/`` longer than 100 lines, unless it says why.

A long function is where the next reader gets lost: it is split along its steps,
each step a named function with explicit inputs and outputs.  A function that
stays long gives a one-line reason, either

- in :data:`LONG_FUNCTIONS` below, keyed ``"path/inside/toolkit.py::qualified.name"``, or
- as a comment on the line of its ``def``: ``def f(...):  # long: <reason>``.

Length is ``end_lineno - lineno + 1`` of the ``def`` node: from the ``def`` line
to the body's last line, docstring and comments included, decorators not.  An allow-list entry whose
function is gone or no longer too long fails the test, so the list only shrinks.
"""

from __future__ import annotations

import ast
from functools import lru_cache
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
TOOLKIT = REPO / "toolkit"
#: The longest a function may be, in lines, without a reason beside it.
MAX_FUNCTION_LINES = 100
#: Marker of the reason comment on a ``def`` line.
REASON_MARKER = "# long:"
#: Functions that stay longer than :data:`MAX_FUNCTION_LINES`, with the reason.
LONG_FUNCTIONS: dict[str, str] = {
    "softbody/global_fit.py::_Problem.evaluate": "one sparse least-squares system: every residual block and its "
                                                 "Jacobian entries laid out in one pass, so their row offsets stay in step",
}


def _functions(path: Path):
    """Every function and method of ``path`` as ``(qualified name, node)``, nested ones included."""
    out = []

    def visit(node, prefix):
        for child in ast.iter_child_nodes(node):
            if isinstance(child, (ast.FunctionDef, ast.AsyncFunctionDef)):
                name = prefix + child.name
                out.append((name, child))
                visit(child, name + ".")
            elif isinstance(child, ast.ClassDef):
                visit(child, prefix + child.name + ".")
            else:
                visit(child, prefix)

    visit(ast.parse(path.read_text(), str(path)), "")
    return out


@lru_cache(maxsize=None)
def _long_functions(root: Path = TOOLKIT) -> dict[str, tuple[int, bool]]:
    """``key -> (length in lines, has a reason comment)`` for every too-long function under ``root``."""
    found = {}
    for path in sorted(root.rglob("*.py")):
        lines = path.read_text().splitlines()
        for name, node in _functions(path):
            length = node.end_lineno - node.lineno + 1
            if length > MAX_FUNCTION_LINES:
                # the reason may sit on the line of ``def`` or on the line closing its signature
                signature = lines[node.lineno - 1:node.body[0].lineno - 1]
                commented = any(REASON_MARKER in line for line in signature)
                found[f"{path.relative_to(root).as_posix()}::{name}"] = (length, commented)
    return found


def test_functions_short_or_give_a_reason():
    found = _long_functions()
    unexplained = [f"toolkit/{key}: {length} lines" for key, (length, commented) in sorted(found.items())
                   if not commented and key not in LONG_FUNCTIONS]
    assert not unexplained, (
        f"functions over {MAX_FUNCTION_LINES} lines: split them along their steps, or give a one-line reason "
        f"('{REASON_MARKER} ...' on the def line, or an entry in LONG_FUNCTIONS):\n" + "\n".join(unexplained))


def test_allow_list_only_shrinks():
    found = _long_functions()
    stale = [key for key in LONG_FUNCTIONS if key not in found]
    assert not stale, f"no longer over {MAX_FUNCTION_LINES} lines (or gone): remove from LONG_FUNCTIONS: {stale}"
    assert all(reason.strip() for reason in LONG_FUNCTIONS.values()), "every allow-list entry needs a reason"


def test_checker_sees_long_nested_and_commented_functions(tmp_path):
    def body(n_lines, indent):
        return "".join(f"{indent}x{i} = {i}\n" for i in range(n_lines))

    path = tmp_path / "nested.py"
    path.write_text("class A:\n    def m(self):\n        def inner():\n" + body(MAX_FUNCTION_LINES, " " * 12))
    lengths = {name: node.end_lineno - node.lineno + 1 for name, node in _functions(path)}
    assert lengths == {"A.m": MAX_FUNCTION_LINES + 2, "A.m.inner": MAX_FUNCTION_LINES + 1}
    # f too long, g too long with a reason, h just short enough
    (tmp_path / "pkg").mkdir()
    (tmp_path / "pkg" / "long.py").write_text(
        "def f():\n" + body(MAX_FUNCTION_LINES, "    ") + "\n\ndef g():  # long: one table\n"
        + body(MAX_FUNCTION_LINES, "    ") + "\n\ndef h():\n" + body(MAX_FUNCTION_LINES - 1, "    "))
    assert dict(_long_functions(tmp_path / "pkg")) == {"long.py::f": (MAX_FUNCTION_LINES + 1, False),
                                                 "long.py::g": (MAX_FUNCTION_LINES + 1, True)}
