"""The package as users see it: stubs for every public name, docstrings, version."""
import ast
import inspect
import pathlib

import meshpde


def stub_names():
    tree = ast.parse((pathlib.Path(meshpde.__file__).parent / "__init__.pyi").read_text(encoding="utf-8"))
    names = set()
    for node in tree.body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            names.add(node.name)
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names.add(node.target.id)
    return names


def test_every_public_name_has_a_stub():
    public = set(meshpde.__all__)
    missing = public - stub_names()
    assert not missing, f"no type stub for {sorted(missing)}"
    for name in public:
        if name == "read_volume" and not meshpde.has_medical:
            continue
        assert hasattr(meshpde, name), name


def test_stubs_ship_with_the_package():
    folder = pathlib.Path(meshpde.__file__).parent
    assert (folder / "py.typed").exists() and (folder / "__init__.pyi").exists()


def test_python_level_functions_document_themselves():
    for f in [meshpde.heat, meshpde.wave, meshpde.fair, meshpde.interpolate, meshpde.correct,
              meshpde.CorrectionSession.apply, meshpde.from_vtk, meshpde.to_vtk]:
        assert f.__doc__ and len(f.__doc__) > 60, f.__name__
        params = inspect.signature(f).parameters
        assert all(p.kind != p.VAR_KEYWORD for p in params.values()), f.__name__  # no **kwargs swallowing typos


def test_version_is_the_projects():
    text = (pathlib.Path(__file__).parents[2] / "CMakeLists.txt").read_text(encoding="utf-8")
    assert f"VERSION {meshpde.__version__} " in text


def test_no_public_signature_shows_a_bare_handle():
    # help() shows what each argument takes (numpy.typing.ArrayLike, os.PathLike | None,
    # ...), never pybind11's "handle".
    import re
    import meshpde._meshpde as ext
    shown = []
    for name, obj in vars(ext).items():
        # Private functions are wrapped by Python functions with their own signatures;
        # a private class's constructor (CorrectionSession's base) is public.
        members = [] if name.startswith("_") else [(name, obj)]
        if isinstance(obj, type):
            members += [(f"{name}.{k}", v) for k, v in vars(obj).items() if not k.startswith("_") or k == "__init__"]
        for full, member in members:
            for line in (getattr(member, "__doc__", None) or "").splitlines():
                shown += [(full, arg) for arg in re.findall(r"(\w+): handle\b", line)]
    assert not shown, shown
