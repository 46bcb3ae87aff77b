"""The packages depend one way: ``core_akf <- sensoropt, impactloc <- akf``; no private name is
imported across packages; sub-commands are entry points.

The import graph is read from the source (every ``import`` and ``from ... import`` statement,
also inside functions), so a lazy import inside a function counts as much as one at the top.
"""
import ast
import pathlib
import subprocess
import sys

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
PACKAGES = ("core_akf", "sensoropt", "impactloc", "akf")
#: what each package may import from this distribution
ALLOWED = {"core_akf": {"core_akf"}, "sensoropt": {"core_akf", "sensoropt"}, "impactloc": {"core_akf", "impactloc"},
           "akf": set(PACKAGES)}


def _imports(package):
    """(module file, imported module, imported names) for every import statement in ``package``."""
    for path in sorted((ROOT / package).rglob("*.py")):
        tree = ast.parse(path.read_text(), str(path))
        parts = list(path.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        for node in ast.walk(tree):
            if isinstance(node, ast.Import):
                for a in node.names:
                    yield path, a.name, []
            elif isinstance(node, ast.ImportFrom):
                if node.level:          # relative: resolve against this module's package
                    base = parts[:len(parts) - node.level] if path.name != "__init__.py" else parts[:len(parts) - node.level + 1]
                    module = ".".join(base + ([node.module] if node.module else []))
                else:
                    module = node.module or ""
                yield path, module, [a.name for a in node.names]


def import_graph():
    """{package: set of packages of this distribution it imports}."""
    graph = {p: set() for p in PACKAGES}
    for package in PACKAGES:
        for _, module, _ in _imports(package):
            top = module.split(".")[0]
            if top in PACKAGES and top != package:
                graph[package].add(top)
    return graph


def test_dependencies_point_one_way():
    graph = import_graph()
    for package, imported in graph.items():
        assert imported <= ALLOWED[package], f"{package} imports {sorted(imported - ALLOWED[package])}"
    assert graph["akf"] == {"core_akf", "sensoropt", "impactloc"}


def test_no_private_name_is_imported_across_packages():
    offences = []
    for package in PACKAGES:
        for path, module, names in _imports(package):
            top = module.split(".")[0]
            if top not in PACKAGES or top == package:
                continue
            private_module = any(p.startswith("_") for p in module.split(".")[1:])
            private_names = [n for n in names if n.startswith("_")]
            if private_module or private_names:
                offences.append(f"{path.relative_to(ROOT)}: from {module} import {names}")
    assert not offences, offences


def _module_name(path):
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def module_graph():
    """{module: set of modules of this distribution it imports} (``from pkg import mod`` counts as
    importing ``pkg.mod``; an import of a package counts as its ``__init__``)."""
    modules = {_module_name(p) for package in PACKAGES for p in (ROOT / package).rglob("*.py")}
    graph = {m: set() for m in modules}
    for package in PACKAGES:
        for path, module, names in _imports(package):
            source = _module_name(path)
            for name in names or [None]:
                target = f"{module}.{name}" if name and f"{module}.{name}" in modules else module
                if target in modules and target != source:
                    graph[source].add(target)
    return graph


def _cycles(graph):
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(sorted(component))
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_import_circle_between_modules():
    """No two modules import each other, directly or round about, also through imports inside
    functions (a package's ``__init__`` importing its own modules is not a circle of theirs unless
    one of them imports the package back)."""
    graph = module_graph()
    for module, imported in graph.items():       # a package's __init__ re-exports: not a dependency of its modules
        imported -= {p for p in PACKAGES if module.startswith(p + ".")}
    assert _cycles(graph) == []


def test_no_private_name_is_imported_across_modules():
    offences = []
    for package in PACKAGES:
        for path, module, names in _imports(package):
            if module.split(".")[0] not in PACKAGES:
                continue
            private = [n for n in names if n.startswith("_") and not n.startswith("__")]
            if private and module != _module_name(path):
                offences.append(f"{path.relative_to(ROOT)}: from {module} import {private}")
    assert not offences, offences


@pytest.mark.parametrize("package", ["core_akf", "sensoropt", "impactloc"])
def test_libraries_import_without_the_application_layer(package):
    code = (f"import sys, {package}, {package}.__init__; "
            "bad = sorted({m.split('.')[0] for m in sys.modules} & {'akf', 'matplotlib'}); print(bad)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_subcommands_are_entry_points():
    from akf.cli import COMMAND_GROUP, build_parser, command_plugins

    plugins = command_plugins()
    assert {"estimate", "place", "locate", "study", "show"} <= set(plugins), plugins
    assert all(ep.group == COMMAND_GROUP for ep in plugins.values())
    parser = build_parser()
    for name in plugins:
        assert parser.parse_args([name] + (["--list"] if name == "study" else ["--list-examples"]
                                           if name != "show" else ["s17_truss"])).command == name


def register_hello(sub):
    """A third-party sub-command, as another package would register it."""
    p = sub.add_parser("hello", help="say hello")
    p.add_argument("--name", default="world")
    p.set_defaults(func=lambda args: print(f"hello {args.name}") or 0)


def test_a_third_party_package_adds_a_subcommand(monkeypatch, capsys):
    from importlib.metadata import EntryPoint

    import akf.cli as cli

    installed = cli.command_plugins()
    plugins = dict(installed, hello=EntryPoint("hello", "test_layers:register_hello", cli.COMMAND_GROUP),
                   broken=EntryPoint("broken", "no_such_package.cli:register", cli.COMMAND_GROUP))
    monkeypatch.setattr(cli, "command_plugins", lambda: plugins)
    assert cli.main(["hello", "--name", "bridge"]) == 0
    captured = capsys.readouterr()
    assert captured.out == "hello bridge\n"
    assert "sub-command 'broken'" in captured.err and "could not be loaded" in captured.err   # akf still works


#: command-line words that the libraries must not use in their messages (the app adds them)
CLI_WORDS = ("CLI:", "--filter", "--resume", "--overwrite", "--allow-undetectable", "in [measurements]",
             "in [filter]", "in [place]", "in [locate]")


@pytest.mark.parametrize("package", ["core_akf", "sensoropt", "impactloc"])
def test_library_messages_name_arguments_not_cli_flags(package):
    """The libraries speak Python (``steady=False``); :func:`akf.cli.cli_wording` turns that into
    the command line's flags and job keys where the app catches the error."""
    offences = []
    for path in sorted((ROOT / package).rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Constant) and isinstance(node.value, str) and not node.value.startswith(">>>"):
                if any(w in node.value for w in CLI_WORDS) and "\n    " not in node.value:     # docstrings aside
                    offences.append(f"{path.relative_to(ROOT)}:{node.lineno}: {node.value[:80]!r}")
    assert not offences, offences


def test_the_command_line_words_the_library_messages():
    """Messages raised by the library, as the command line prints them."""
    import numpy as np

    from akf.cli import cli_wording
    from core_akf import estimate
    from core_akf.checks import UndetectableError
    from core_akf.io.units import conversion
    from core_akf.models import s17_truss

    acc_only = ["acc:4:y", "acc:8:y"]
    kw = dict(model_error_cov=1e-16, force_increment_cov=1e4, noise_cov=1e-4)
    with pytest.raises(UndetectableError) as undetectable:
        estimate(s17_truss(), acc_only, ["8:y"], np.zeros((64, 2)), 1e-3, **kw)
    assert "--allow-undetectable" in cli_wording(str(undetectable.value))
    with pytest.raises(ValueError) as no_steady:
        estimate(s17_truss(), acc_only, ["8:y"], np.zeros((64, 2)), 1e-3, steady=True, allow_undetectable=True, **kw)
    assert "use --filter time-varying" in cli_wording(str(no_steady.value))
    with pytest.raises(ValueError) as bridge:
        conversion("mV/V", "strain", "SG1")
    assert "give its gauge_factor in [measurements]" in cli_wording(str(bridge.value))


def test_no_module_writes_into_another_objects_dict():
    """Caches live with their owner (``Structure.memo``, ``cached_property``), not in another
    object's ``__dict__``."""
    offences = []
    for package in ("core_akf", "sensoropt", "impactloc"):
        for path in sorted((ROOT / package).rglob("*.py")):
            for k, line in enumerate(path.read_text().splitlines(), start=1):
                if "__dict__" in line and "self.__dict__" not in line:
                    offences.append(f"{path.relative_to(ROOT)}:{k}: {line.strip()}")
    assert not offences, offences


def test_the_filter_kernels_know_no_structure_or_sensors():
    """The kernels are pure functions over matrices and a built Filter: they import neither the
    structures nor the sensors (those are the Filter's business, once)."""
    kernels = ROOT / "core_akf" / "filter" / "kernels.py"
    imported = {module for path, module, names in _imports("core_akf") if path == kernels}
    imported |= {f"{module}.{n}" for path, module, names in _imports("core_akf") if path == kernels for n in names}
    assert imported, "the kernels' imports were not read"
    assert not {m for m in imported if m.split(".")[:2] in (["core_akf", "sensors"], ["core_akf", "structure"])}


def test_no_module_reaches_into_an_estimator():
    """An Estimator is used through its methods (update, smooth, state, restore, ...): no module
    outside the filter package reads its filter set-up or its private state."""
    offences = []
    for package in PACKAGES:
        for path in sorted((ROOT / package).rglob("*.py")):
            if path.parent == ROOT / "core_akf" / "filter":
                continue
            for node in ast.walk(ast.parse(path.read_text(), str(path))):
                if (isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name)
                        and "estimator" in node.value.id.lower()
                        and (node.attr in ("setup", "filter") or node.attr.startswith("_"))):
                    offences.append(f"{path.relative_to(ROOT)}:{node.lineno}: {node.value.id}.{node.attr}")
    assert not offences, offences


def test_every_module_imports_first():
    """Each module of the distribution imports on its own, first (an import circle through a
    package's ``__init__`` fails only when a module inside it is the first one imported)."""
    code = f"""
import importlib, pathlib, sys
root = pathlib.Path({str(ROOT)!r})
names = []
for package in {PACKAGES!r}:
    for path in sorted((root / package).rglob("*.py")):
        parts = list(path.relative_to(root).with_suffix("").parts)
        if parts[-1] != "__main__":
            names.append(".".join(parts[:-1] if parts[-1] == "__init__" else parts))
failed = []
for name in names:
    for loaded in [m for m in sys.modules if m.split(".")[0] in {PACKAGES!r}]:
        del sys.modules[loaded]
    try:
        importlib.import_module(name)
    except Exception as exc:
        failed.append(f"{{name}}: {{type(exc).__name__}}: {{exc}}")
print(len(names)); print("\\n".join(failed))
"""
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.splitlines()
    failed = [line for line in out[1:] if line]
    assert int(out[0]) > 80 and failed == [], failed
