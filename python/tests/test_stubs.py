"""The type stubs (python/cartesian_impedance/*.pyi, written by python/generate_stubs.py) against
the module they describe: every public name of the module and of each of its classes is in the
stubs, the stubs name nothing the module lacks, and they are what the generator writes now. So a
binding added or renamed without regenerating them fails here, not silently in an editor."""

import ast
import pathlib
import subprocess
import sys
import types

import pytest

import cartesian_impedance as ci
from conftest import SOURCE_DIR, has_sim

STUB_DIR = SOURCE_DIR / "python" / "cartesian_impedance"
GENERATOR = SOURCE_DIR / "python" / "generate_stubs.py"


def stub_names(path):
    """{None: names at the top level, class name: names in the class} of a stub file."""
    tree = ast.parse(path.read_text(), str(path))
    names = {None: set()}

    def targets(statements):
        found = set()
        for node in statements:
            if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
                found.add(node.name)
            elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
                found.add(node.target.id)
            elif isinstance(node, ast.ImportFrom) and node.module is None:  # from . import sim
                found.update(alias.asname or alias.name for alias in node.names)
        return found

    names[None] = targets(tree.body)
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            names[node.name] = targets(node.body)
    return names


def public(names):
    return {name for name in names if not name.startswith("_")}


def extension_names(module):
    """The public names of `module` that the stubs describe: not the package's pure-Python
    submodules (cartesian_impedance.envs), which are attributes once imported and which type
    checkers read from their own sources."""
    return {name for name in public(vars(module))
            if not (isinstance(getattr(module, name), types.ModuleType) and
                    str(getattr(getattr(module, name), "__file__", "")).endswith(".py"))}


def modules():
    found = [(ci, STUB_DIR / "__init__.pyi"), (ci.runtime, STUB_DIR / "runtime.pyi")]
    if has_sim():
        found.append((ci.sim, STUB_DIR / "sim.pyi"))
    return found


@pytest.mark.parametrize("module, stub", modules(), ids=lambda value: getattr(value, "__name__", ""))
def test_the_stubs_name_every_public_attribute(module, stub):
    names = stub_names(stub)
    missing = sorted(extension_names(module) - names[None])
    assert not missing, f"{module.__name__} has {missing}, which {stub.name} lacks"
    for name in public(vars(module)):
        value = getattr(module, name)
        if not isinstance(value, type):
            continue
        lacking = sorted(public(vars(value)) - names[name])
        assert not lacking, f"{module.__name__}.{name} has {lacking}, which {stub.name} lacks"


@pytest.mark.parametrize("module, stub", modules(), ids=lambda value: getattr(value, "__name__", ""))
def test_the_stubs_name_nothing_the_module_lacks(module, stub):
    names = stub_names(stub)
    extra = sorted(public(names[None]) - public(vars(module)))
    assert not extra, f"{stub.name} names {extra}, which {module.__name__} lacks"
    for name, members in names.items():
        if name is None:
            continue
        extra = sorted(public(members) - set(dir(getattr(module, name))))
        assert not extra, f"{stub.name}: {name} names {extra}, which {module.__name__}.{name} lacks"


def test_the_stubs_are_what_the_generator_writes():
    if not has_sim() or not ci.sim.engine_available("dart")[0]:
        pytest.skip("the stubs describe a build with the simulation and DART")
    result = subprocess.run([sys.executable, str(GENERATOR), "--check"], capture_output=True,
                            text=True)
    assert result.returncode == 0, result.stdout + result.stderr


def test_the_stubs_and_py_typed_sit_beside_the_module():
    # Editors and type checkers look for them there (PEP 561), in the build tree as in an install.
    package = pathlib.Path(ci.__file__).parent
    for name in ["__init__.pyi", "runtime.pyi", "py.typed"] + (["sim.pyi"] if has_sim() else []):
        assert (package / name).is_file(), f"{package} lacks {name}"
    assert isinstance(ci._core, types.ModuleType)


@pytest.mark.parametrize("old, new, named", [
    ("class Targets:", "class _Gone:", "Targets"),
    ("    def set_wrench(", "    def _gone(", "set_wrench"),
])
def test_a_stub_that_falls_behind_is_caught(tmp_path, old, new, named):
    # The check above can fail: a stub without a class, or a class without a method, is caught.
    stub = (STUB_DIR / "__init__.pyi").read_text()
    assert old in stub
    path = tmp_path / "__init__.pyi"
    path.write_text(stub.replace(old, new, 1))
    with pytest.raises(AssertionError, match=named):
        test_the_stubs_name_every_public_attribute(ci, path)
