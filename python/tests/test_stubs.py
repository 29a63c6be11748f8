"""The type stubs describe what the package has: every public name, class and method."""

from __future__ import annotations

import ast
import importlib
import pathlib

import chronomap

PACKAGE = pathlib.Path(chronomap.__file__).parent


def _module(path):
    return chronomap if path.stem == "__init__" else importlib.import_module(f"chronomap.{path.stem}")


def _classes(tree):
    return {node.name: node for node in tree.body if isinstance(node, ast.ClassDef)}


def _functions(tree):
    return {node.name for node in tree.body if isinstance(node, ast.FunctionDef)}


def test_every_public_name_has_a_stub():
    stubs = {}
    for path in PACKAGE.glob("*.pyi"):
        tree = ast.parse(path.read_text())
        stubs.update(_classes(tree))
        stubs.update({f: None for f in _functions(tree)})
    missing = [name for name in chronomap.__all__ if name not in stubs]
    assert not missing, f"no stub for {missing}"


def test_every_stubbed_method_exists():
    for path in PACKAGE.glob("*.pyi"):
        for name, node in _classes(ast.parse(path.read_text())).items():
            runtime = getattr(_module(path), name)
            for item in node.body:
                if isinstance(item, ast.FunctionDef) and not item.name.startswith("_"):
                    assert hasattr(runtime, item.name), f"{path.name}: {name}.{item.name}"


def test_every_runtime_method_has_a_stub():
    classes = {}
    for path in PACKAGE.glob("*.pyi"):
        classes.update(_classes(ast.parse(path.read_text())))
    for name in chronomap.__all__:
        runtime = getattr(chronomap, name)
        if not isinstance(runtime, type):
            continue
        stubbed = {item.name for cls in runtime.__mro__ if cls.__name__ in classes
                   for item in classes[cls.__name__].body if isinstance(item, ast.FunctionDef)}
        public = {m for m in vars(runtime) if not m.startswith("_")}
        assert public <= stubbed, f"{name}: no stub for {sorted(public - stubbed)}"


def test_docstrings():
    for name in chronomap.__all__:
        assert getattr(chronomap, name).__doc__, f"{name} has no docstring"


def test_sources_parse_as_python_3_9():
    # The wheel is abi3 for CPython >= 3.9 (pyproject.toml): the package's own Python must
    # not use newer syntax (CI runs 3.11; docs/python.md says how 3.9 and 3.13 were tried).
    for path in sorted(PACKAGE.glob("*.py")) + sorted((PACKAGE.parent / "tests").glob("*.py")):
        ast.parse(path.read_text(), filename=str(path), feature_version=(3, 9))
