"""Every public function, method and class of the library packages documents every parameter in
numpydoc form (``name : type``), as python-control's ``docstrings_test.py`` checks its own.

Public: a name without a leading underscore, defined in a module of ``core_akf``, ``sensoropt``
or ``impactloc`` (re-exports are checked where they are defined).  A class documents the
parameters of its constructor in its own docstring (or its ``__init__``'s); a method's docstring
may be inherited from the method it overrides.  ``*args`` and ``**kwargs`` are documented as
``*args`` / ``**kwargs``.
"""
import importlib
import inspect
import pkgutil
import re

import pytest

PACKAGES = ("core_akf", "sensoropt", "impactloc")


def _modules():
    for name in PACKAGES:
        package = importlib.import_module(name)
        yield package
        for info in pkgutil.walk_packages(package.__path__, name + "."):
            yield importlib.import_module(info.name)


def _callables():
    """``(qualified name, callable for the signature, docstring)`` of every public function,
    method and class."""
    seen = set()
    for module in _modules():
        for name, obj in sorted(vars(module).items()):
            if name.startswith("_") or getattr(obj, "__module__", None) != module.__name__ or id(obj) in seen:
                continue
            if inspect.isfunction(obj):
                seen.add(id(obj))
                yield f"{module.__name__}.{obj.__qualname__}", obj, inspect.getdoc(obj)
            elif inspect.isclass(obj):
                seen.add(id(obj))
                name = obj.__qualname__          # an alias (a class's old name) is checked under its own
                if obj.__doc__ is None or (issubclass(obj, BaseException) and "__init__" not in vars(obj)):
                    yield f"{module.__name__}.{name}", None, obj.__doc__      # an exception: a docstring is enough
                else:
                    init = vars(obj).get("__init__")
                    doc = (inspect.getdoc(obj) or "") + "\n" + (inspect.getdoc(init) or "" if init else "")
                    takes = init if init is not None else (obj if "__dataclass_fields__" in vars(obj) else None)
                    if getattr(obj, "_is_protocol", False):
                        takes = None          # a Protocol is not built: its attributes are documented
                    yield f"{module.__name__}.{name}", takes, doc
                for attr, member in sorted(vars(obj).items()):
                    if attr.startswith("_"):
                        continue
                    func = member.__func__ if isinstance(member, (staticmethod, classmethod)) else member
                    if inspect.isfunction(func):
                        yield f"{module.__name__}.{name}.{attr}", func, inspect.getdoc(getattr(obj, attr))


CALLABLES = list(_callables())


def _documented(name, doc):
    """``name`` in a numpydoc parameter line: ``name : type``, also in a list ``a, name : type``,
    or a line of names alone (the type left out)."""
    names = r"((\*{0,2}\w+), )*"
    return re.search(r"(^|\n)[ ]*" + names + re.escape(name) + r"(, \*{0,2}\w+)*( :|\n|$)", doc) is not None


def _parameters(func):
    try:
        signature = inspect.signature(func)
    except (TypeError, ValueError):
        return []
    out = []
    for name, p in signature.parameters.items():
        if name in ("self", "cls") or name.startswith("_"):
            continue
        out.append({p.VAR_POSITIONAL: f"*{name}", p.VAR_KEYWORD: f"**{name}"}.get(p.kind, name))
    return out


def test_the_packages_have_public_callables():
    assert len(CALLABLES) > 300


@pytest.mark.parametrize("package", PACKAGES)
def test_every_public_callable_has_a_docstring(package):
    missing = [q for q, _, doc in CALLABLES if q.startswith(package + ".") and not (doc or "").strip()]
    assert not missing, missing


@pytest.mark.parametrize("package", PACKAGES)
def test_every_parameter_is_documented(package):
    undocumented = []
    for qualified, func, doc in CALLABLES:
        if not qualified.startswith(package + ".") or func is None:
            continue
        bad = [p for p in _parameters(func) if not _documented(p, doc or "")]
        if bad:
            undocumented.append(f"{qualified}: {', '.join(bad)}")
    assert not undocumented, f"{len(undocumented)} callables with undocumented parameters:\n" + "\n".join(undocumented)


def _returns_a_value(func):
    """Whether ``func`` has a ``return value`` or a ``yield`` of its own (not of a nested function)."""
    import ast
    import textwrap

    try:
        tree = ast.parse(textwrap.dedent(inspect.getsource(func)))
    except (OSError, TypeError, SyntaxError):
        return False
    top = tree.body[0]
    nested = {id(n) for d in ast.walk(top) if d is not top and isinstance(d, (ast.FunctionDef, ast.Lambda))
              for n in ast.walk(d)}
    for node in ast.walk(top):
        if id(node) in nested:
            continue
        if isinstance(node, (ast.Yield, ast.YieldFrom)):
            return True
        if isinstance(node, ast.Return) and node.value is not None and not (
                isinstance(node.value, ast.Constant) and node.value.value is None):
            return True
    return False


@pytest.mark.parametrize("package", PACKAGES)
def test_what_a_function_returns_is_documented(package):
    """A function that returns or yields a value has a Returns or Yields section."""
    missing = []
    for qualified, func, doc in CALLABLES:
        if (not qualified.startswith(package + ".") or func is None or not inspect.isfunction(func)
                or func.__name__ == "__init__"):
            continue
        if _returns_a_value(func) and not re.search(r"\n(Returns|Yields)\n-+\n", doc or ""):
            missing.append(qualified)
    assert not missing, missing


def test_the_check_finds_an_undocumented_parameter():
    def documented(a, b):
        """Parameters
        ----------
        a, b : float
        """

    def half(a, b):
        """Parameters
        ----------
        a : float
            Mentions b in prose only.
        """
    assert all(_documented(p, inspect.getdoc(documented)) for p in _parameters(documented))
    assert [p for p in _parameters(half) if not _documented(p, inspect.getdoc(half))] == ["b"]


# ----------------------------------------------------------------------------- type hints
#: the public API: what these modules export (``__all__``), and the classes a user builds beside them
API_MODULES = ("core_akf", "core_akf.models", "core_akf.loads", "core_akf.io", "sensoropt", "impactloc")
API_EXTRA = ("core_akf.filter.streaming.Estimator", "core_akf.covariances.noise_covariance")


def _api():
    """``(qualified name, function)`` of every function, constructor and public method of the API."""
    objects = []
    for name in API_MODULES:
        module = importlib.import_module(name)
        exported = getattr(module, "__all__", None) or [n for n in vars(module) if not n.startswith("_")]
        objects += [(f"{name}.{n}", getattr(module, n)) for n in exported]
    for qualified in API_EXTRA:
        module, name = qualified.rsplit(".", 1)
        objects.append((qualified, getattr(importlib.import_module(module), name)))
    out, seen = [], set()
    for qualified, obj in objects:
        if id(obj) in seen or not (inspect.isfunction(obj) or inspect.isclass(obj)):
            continue
        seen.add(id(obj))
        if inspect.isfunction(obj):
            out.append((qualified, obj))
            continue
        if issubclass(obj, BaseException) or getattr(obj, "_is_protocol", False):
            continue
        init = vars(obj).get("__init__")
        if init is not None and "__dataclass_fields__" not in vars(obj):    # a dataclass's fields are annotated
            out.append((qualified, init))
        for attr, member in vars(obj).items():
            func = member.__func__ if isinstance(member, (staticmethod, classmethod)) else member
            if not attr.startswith("_") and inspect.isfunction(func):
                out.append((f"{qualified}.{attr}", func))
    return out


def test_the_public_api_is_annotated():
    """Every parameter and every return of the public API has a type hint (the array aliases of
    :mod:`core_akf.checks` carry shapes and units)."""
    missing = []
    for qualified, func in _api():
        signature = inspect.signature(func)
        bare = [n for n, p in signature.parameters.items() if n not in ("self", "cls")
                and p.annotation is inspect.Parameter.empty]
        if func.__name__ != "__init__" and signature.return_annotation is inspect.Signature.empty:
            bare.append("return")
        if bare:
            missing.append(f"{qualified}: {', '.join(bare)}")
    assert len(_api()) > 100
    assert not missing, "\n".join(missing)


def test_the_annotations_name_real_types():
    """The string annotations resolve (a typo in a hint is a test failure, not a silent string)."""
    import typing

    failures = []
    for qualified, func in _api():
        module = importlib.import_module(func.__module__)
        namespace = dict(vars(module))
        for extra in ("core_akf.structure", "core_akf.filter", "core_akf.sensors", "sensoropt.encoding",
                      "sensoropt.objective", "impactloc.scan", "impactloc.locate", "impactloc.tuning",
                      "impactloc.reconstruct", "core_akf.io.readers"):
            namespace.update({k: v for k, v in vars(importlib.import_module(extra)).items() if not k.startswith("_")})
        import numpy
        import pandas
        import scipy.sparse
        from matplotlib.figure import Figure

        namespace.update(np=numpy, pd=pandas, scipy=scipy, Figure=Figure)
        try:
            typing.get_type_hints(func, globalns=namespace)
        except Exception as exc:  # noqa: BLE001 -- any failure names the function
            failures.append(f"{qualified}: {type(exc).__name__}: {exc}")
    assert not failures, "\n".join(failures)


# ----------------------------------------------------------------------------- examples
#: the classes a user builds (results are shown by the examples of the functions that return them)
BUILT_CLASSES = ("core_akf.Structure", "core_akf.filter.streaming.Estimator", "core_akf.io.Record", "sensoropt.CandidateSet",
                 "sensoropt.FunctionObjective", "sensoropt.PlacementProblem", "impactloc.Covariances")


def test_the_api_has_examples():
    """Every function the API exports (figures aside) and every class a user builds has an
    Examples section; tests/test_docs.py runs them (doctest)."""
    missing = []
    for name in API_MODULES:
        module = importlib.import_module(name)
        exported = getattr(module, "__all__", None) or [n for n in vars(module) if not n.startswith("_")]
        for n in exported:
            obj = getattr(module, n)
            if (inspect.isfunction(obj) and obj.__module__.split(".")[0] in PACKAGES and not n.startswith("plot_")
                    and "\nExamples\n--" not in (inspect.getdoc(obj) or "")):
                missing.append(f"{name}.{n}")
    for qualified in BUILT_CLASSES:
        module, n = qualified.rsplit(".", 1)
        if "\nExamples\n--" not in (inspect.getdoc(getattr(importlib.import_module(module), n)) or ""):
            missing.append(qualified)
    assert not missing, missing
