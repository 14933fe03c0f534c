"""scripts/code_size.py: what it counts, and the module size limit on the tree."""

from __future__ import annotations

import importlib.util
import sys
import textwrap
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def _code_size():
    spec = importlib.util.spec_from_file_location("code_size", ROOT / "scripts" / "code_size.py")
    assert spec is not None and spec.loader is not None
    mod = importlib.util.module_from_spec(spec)
    sys.modules["code_size"] = mod
    spec.loader.exec_module(mod)
    return mod


def test_function_length_leaves_the_docstring_out() -> None:
    text = textwrap.dedent(
        '''
        def f(x):
            """Two
            lines."""
            y = x + 1
            return y


        class A:
            def m(self):
                def inner():
                    return 1

                return inner()
        '''
    )
    assert dict(_code_size()._functions("pkg.mod", text)) == {
        "pkg.mod:f": 3,  # def, two statements
        "pkg.mod:A.m": 5,
        "pkg.mod:A.m.inner": 2,
    }


def test_no_module_of_the_working_tree_is_over_the_limit() -> None:
    cs = _code_size()
    sizes = cs.measure(".")
    assert sizes.modules, "no module read"
    too_long = [(p, n) for p, n in sizes.modules if n > cs.LONG_MODULE]
    assert not too_long, too_long


def test_report_compares_two_revisions() -> None:
    out = _code_size().report("HEAD", ".", 3)
    assert "| modules |" in out and "### Longest functions" in out
    assert out.count("\n| 1 | `") == 2  # one module table, one function table


def test_no_function_of_the_working_tree_is_over_the_limit() -> None:
    cs = _code_size()
    sizes = cs.measure(".")
    assert sizes.functions, "no function read"
    too_long = [(f, n) for f, n in sizes.functions if n > cs.LONG_FUNCTION]
    assert not too_long, too_long
