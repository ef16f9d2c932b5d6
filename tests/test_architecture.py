"""The package's shape: no import cycles between modules or between packages (function-level
imports included), layers that point one way, command-line programs only in ``cli/`` and its
thin entry points, no module over the size a reader can hold in mind, and no function with
more parameters than a reader can hold in mind either.

The import graph counts every import that can run (``if TYPE_CHECKING:`` blocks left out) and
the two dynamic forms the package uses: ``kernel_module("swarmplan....")`` (the loader of
compiled kernels) and ``importlib.import_module(f"swarmplan.x.{...}")`` (counted as importing
every module under ``swarmplan.x``)."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "swarmplan"
MAX_LINES = 600
MAX_PARAMETERS = 12


def module_name(path: Path) -> str:
    parts = list(path.relative_to(PACKAGE.parent).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def runtime_nodes(tree: ast.AST, annotations: bool = False) -> list[ast.AST]:
    """Every node that can run: ``if TYPE_CHECKING:`` blocks (annotations only) are left out,
    unless ``annotations``."""
    out: list[ast.AST] = []
    todo = [tree]
    while todo:
        node = todo.pop()
        out.append(node)
        for child in ast.iter_child_nodes(node):
            if (
                not annotations
                and isinstance(child, ast.If)
                and ast.unparse(child.test)
                in (
                    "TYPE_CHECKING",
                    "typing.TYPE_CHECKING",
                )
            ):
                todo.extend(child.orelse)
                continue
            todo.append(child)
    return out


def dynamic_imports(node: ast.AST, files: dict[str, Path]) -> list[str] | None:
    """The modules a call imports by name (see the module docstring), None for any other node;
    a dynamic import whose module cannot be read off the call is an error. A module looked up
    by name (``sys.modules["swarmplan...."]``) counts as imported too."""
    if (
        isinstance(node, ast.Subscript)
        and ast.unparse(node.value) == "sys.modules"
        and isinstance(node.slice, ast.Constant)
        and str(node.slice.value).startswith("swarmplan")
    ):
        return [str(node.slice.value)]
    if not isinstance(node, ast.Call):
        return None
    func = node.func
    name = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
    if name not in ("kernel_module", "import_module") or not node.args:
        return None
    arg = node.args[0]
    if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
        return [arg.value]
    if (
        isinstance(arg, ast.JoinedStr)
        and arg.values
        and isinstance(arg.values[0], ast.Constant)
        and str(arg.values[0].value).startswith("swarmplan.")
    ):
        prefix = str(arg.values[0].value)
        return [m for m in files if m.startswith(prefix)]
    return ["<unknown: " + ast.unparse(node) + ">"]


_GRAPHS: dict[tuple[Path, bool, bool], dict[str, set[str]]] = {}


def import_graph(annotations: bool = False, implicit_packages: bool = True) -> dict[str, set[str]]:
    """Module -> our modules it imports anywhere it can run (function level included), and with
    ``annotations`` in ``if TYPE_CHECKING:`` blocks too.

    Importing ``a.b.c`` also runs the packages ``a.b`` and ``a`` first; those count as
    imported too (unless ``implicit_packages`` is false), unless they are packages the importer itself
    lives in (already running). Each graph is read from the sources once per test run (a copy
    each call).
    """
    key = (PACKAGE, annotations, implicit_packages)
    if key not in _GRAPHS:
        _GRAPHS[key] = _read_import_graph(annotations, implicit_packages)
    return {mod: set(targets) for mod, targets in _GRAPHS[key].items()}


def _read_import_graph(annotations: bool, implicit_packages: bool) -> dict[str, set[str]]:
    files = {module_name(p): p for p in PACKAGE.rglob("*.py")}
    packages = {module_name(p) for p in PACKAGE.rglob("__init__.py")}
    graph: dict[str, set[str]] = {}
    for mod, path in files.items():
        own = mod if mod in packages else mod.rpartition(".")[0]
        targets: set[str] = set()
        for node in runtime_nodes(ast.parse(path.read_text(encoding="utf-8")), annotations):
            names: list[str] = dynamic_imports(node, files) or []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = own.split(".")[: len(own.split(".")) - node.level + 1]
                    base = ".".join(anchor + ([base] if base else []))
                names = [base] + [f"{base}.{a.name}" for a in node.names]
            for name in names:
                # ``import a.b.c`` runs the packages ``a`` and ``a.b`` first, unless the importer
                # lives in them (then they are already running).
                while name:
                    running = own == name or own.startswith(name + ".")
                    if name in files and not running:
                        targets.add(name)
                    name = name.rpartition(".")[0] if implicit_packages else ""
        targets.discard(mod)
        graph[mod] = targets
    return graph


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_cycle_finder_finds_a_cycle() -> None:
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycles() -> None:
    assert cycles(import_graph()) == []


def test_no_files_import_each_other_even_for_annotations() -> None:
    """No two files import each other, directly or in a circle, counting the imports of
    annotations and modules looked up by name (``sys.modules[...]``): a file's code, types and
    state are its own, read by the files above it."""
    assert cycles(import_graph(annotations=True, implicit_packages=False)) == []


def test_file_circle_finder_sees_annotations_and_lookups(tmp_path: Path, monkeypatch) -> None:
    pkg = tmp_path / "swarmplan"
    pkg.mkdir()
    (pkg / "__init__.py").write_text("")
    (pkg / "a.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from swarmplan.b import B\n"
    )
    (pkg / "b.py").write_text("import sys\n\ndef f():\n    return sys.modules['swarmplan.a']\n")
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", pkg)
    assert cycles(import_graph()) == []
    assert cycles(import_graph(annotations=True, implicit_packages=False)) == [["swarmplan.a", "swarmplan.b"]]


def test_no_module_over_max_lines() -> None:
    sizes = {module_name(p): len(p.read_text(encoding="utf-8").splitlines()) for p in PACKAGE.rglob("*.py")}
    assert {m: n for m, n in sizes.items() if n > MAX_LINES} == {}


#: The simulation orchestrates (its steps' work lives in ``sim``'s modules it calls).
MAX_SIMULATION_LINES = 300


def test_the_simulation_stays_orchestration() -> None:
    tree = ast.parse((PACKAGE / "sim" / "env.py").read_text(encoding="utf-8"))
    (cls,) = [n for n in tree.body if isinstance(n, ast.ClassDef) and n.name == "Simulation"]
    assert cls.end_lineno - cls.lineno + 1 <= MAX_SIMULATION_LINES


def parameter_count(node: ast.FunctionDef | ast.AsyncFunctionDef) -> int:
    """The parameters a caller passes: every kind (``*args`` and ``**kwargs`` one each), less a
    method's ``self`` or ``cls``."""
    a = node.args
    n = len(a.posonlyargs) + len(a.args) + len(a.kwonlyargs) + (a.vararg is not None) + (a.kwarg is not None)
    first = (a.posonlyargs + a.args)[:1]
    return n - (bool(first) and first[0].arg in ("self", "cls"))


def long_parameter_lists(root: Path) -> dict[str, int]:
    out = {}
    for path in root.rglob("*.py"):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                continue
            if parameter_count(node) > MAX_PARAMETERS:
                out[f"{path.relative_to(root).as_posix()}:{node.name}"] = parameter_count(node)
    return out


def test_no_function_takes_more_than_max_parameters() -> None:
    """Values that travel together travel as one (a tuple into a kernel, a dataclass elsewhere)."""
    assert long_parameter_lists(PACKAGE) == {}


def test_parameter_count_sees_every_kind_and_skips_self(tmp_path: Path) -> None:
    names = ", ".join(f"a{k}" for k in range(10))
    (tmp_path / "m.py").write_text(
        f"def f({names}, *rest, key, **kw): pass\n"
        f"class C:\n    def g(self, {names}, x, y): pass\n    def h(self, {names}, x, y, z): pass\n"
    )
    assert long_parameter_lists(tmp_path) == {"m.py:f": 13, "m.py:h": 13}


def test_every_module_imports() -> None:
    """A moved name leaves no import behind that points at its old home."""
    import importlib

    for mod in sorted(import_graph()):
        if not mod.endswith("__main__"):
            importlib.import_module(mod)


# ------------------------------------------------------------------ packages and layers

TOP_LEVEL = {"swarmplan", "swarmplan.core", "swarmplan.run", "swarmplan.compare"}
"""The only modules outside a subpackage: the root, the shared types and two ``python -m``
entry points."""

LAYERS: tuple[tuple[str, ...], ...] = (
    ("runtime",),  # process settings (BLAS threads), the loader of compiled kernels
    ("core", "optimizers"),  # the simulation's shared types; the metaheuristics (standalone)
    ("geometry",),  # shapes, distances, swept collision checks, neighbours
    ("world",),  # world files -> typed World (planner and tracker settings included)
    ("flight",),  # potential field, kinematic limits, fixed-wing look-ahead
    ("planner",),  # global routes, escapes, smoothing (optimizers over segment costs)
    ("sim",),  # one run: reset/step, safety filter, contacts, metrics
    ("io",),  # MCAP logs, Foxglove scene, running a world to a log
    ("replay", "sweep"),  # reading logs back; studies over worlds x optimizers x seeds
    ("track", "bench"),  # flying logs with a quadrotor; benchmarks
    ("export",),  # flown paths as vehicle files (Crazyflie, PX4/ArduPilot), flown again to check them
    ("cli",),  # the command-line programs
)
"""Bottom to top: a package imports only from layers below its own (the root package, which
imports nothing, from anywhere)."""


def is_entry_point(mod: str) -> bool:
    """``python -m`` entry points: ``swarmplan.x.__main__`` and the top-level run/compare."""
    return mod.endswith(".__main__") or mod in ("swarmplan.run", "swarmplan.compare")


def package_of(mod: str) -> str:
    """``swarmplan.x.y`` -> ``x``; ``swarmplan.core`` -> ``core``; the root -> ``swarmplan``."""
    parts = mod.split(".")
    return parts[1] if len(parts) > 1 else parts[0]


def package_graph(graph: dict[str, set[str]]) -> dict[str, set[str]]:
    """Package -> packages its modules import (entry points, which nothing imports, left out)."""
    out: dict[str, set[str]] = {}
    for mod, targets in graph.items():
        if is_entry_point(mod):
            continue
        src = package_of(mod)
        out.setdefault(src, set()).update(package_of(t) for t in targets if package_of(t) != src)
    for targets in list(out.values()):
        for t in targets:
            out.setdefault(t, set())
    return out


def test_every_dynamic_import_names_its_module() -> None:
    """Outside the command line (and the kernel loader itself) a dynamic import's module can be
    read off the call, so the graph above sees it."""
    files = {module_name(p): p for p in PACKAGE.rglob("*.py")}
    unknown = {
        f"{mod}: {name}"
        for mod, path in files.items()
        if not mod.startswith("swarmplan.cli.") and mod != "swarmplan.runtime.compiled"
        for node in runtime_nodes(ast.parse(path.read_text(encoding="utf-8")))
        for name in dynamic_imports(node, files) or []
        if name.startswith("<")
    }
    assert unknown == set()


def test_no_package_level_cycles() -> None:
    assert cycles(package_graph(import_graph())) == []


def test_package_cycle_finder_sees_function_level_imports(tmp_path: Path) -> None:
    """Negative control: a loop made only by a function-level import is found."""
    graph = {"swarmplan.world.a": {"swarmplan.geometry.b"}, "swarmplan.geometry.b": set()}
    assert cycles(package_graph(graph)) == []
    graph["swarmplan.geometry.b"] = {"swarmplan.world.a"}
    assert cycles(package_graph(graph)) == [["geometry", "world"]]


def test_layers_point_one_way() -> None:
    rank = {pkg: k for k, layer in enumerate(LAYERS) for pkg in layer}
    pkgs = package_graph(import_graph())
    assert sorted(set(pkgs) - {"swarmplan"}) == sorted(rank), "every package has a layer"
    upward = {
        f"{src} -> {dst}"
        for src, targets in pkgs.items()
        for dst in targets
        if dst != "swarmplan" and (src == "swarmplan" or rank[dst] >= rank[src])
    }
    assert upward == set()


def test_world_imports_nothing_above_geometry() -> None:
    above = {"flight", "planner", "sim", "io", "cli", "track", "replay", "sweep", "bench"}
    graph = import_graph()
    leaks = {
        f"{m} -> {t}"
        for m, ts in graph.items()
        if package_of(m) == "world"
        for t in ts
        if package_of(t) in above
    }
    assert leaks == set()


def test_only_entry_points_import_the_command_line() -> None:
    graph = import_graph()
    callers = {
        m
        for m, ts in graph.items()
        if any(package_of(t) == "cli" for t in ts) and package_of(m) != "cli" and not is_entry_point(m)
    }
    assert callers == set()


def test_top_level_holds_only_core_and_thin_entry_points() -> None:
    top = {module_name(p) for p in PACKAGE.glob("*.py")}
    assert top == TOP_LEVEL
    for mod in sorted(m for m in import_graph() if is_entry_point(m)):
        path = PACKAGE.parent / (mod.replace(".", "/") + ".py")
        text = path.read_text(encoding="utf-8")
        ours = [t for t in import_graph()[mod] if t != "swarmplan.cli"]
        assert len(ours) == 1 and ours[0].startswith("swarmplan.cli."), (mod, ours)
        assert len(text.splitlines()) <= 12, mod


def test_readme_layout_lists_every_package_bottom_up() -> None:
    """The README's layout table has a row per package (and core.py), in the order of LAYERS."""
    import re

    text = (PACKAGE.parent / "README.md").read_text(encoding="utf-8")
    section = text.split("## Layout (data flow)", 1)[1].split("\n## ", 1)[0]
    rows = re.findall(r"^\| `swarmplan/([a-z_]+)(?:/|\.py)` \|", section, re.M)
    packages = sorted(p.name for p in PACKAGE.iterdir() if (p / "__init__.py").is_file())
    assert sorted(rows) == sorted([*packages, "core"])
    rank = {pkg: k for k, layer in enumerate(LAYERS) for pkg in layer}
    assert [rank[r] for r in rows] == sorted(rank[r] for r in rows)


LAZY_IMPORTS: dict[tuple[str, str], str] = {
    ("swarmplan.io.runner", "swarmplan.io.recording"): "mcap and protobuf only when a log is written",
    ("swarmplan.planner", "swarmplan.planner.global_path"): "cost models and encodings only in mode: global",
    ("swarmplan.replay.recording", "swarmplan.replay.geometry"): "scipy rotations for untracked obstacles",
    ("swarmplan.track.output", "swarmplan.io.foxglove_scene"): "Foxglove schemas only for a scene",
    ("swarmplan.track.output", "swarmplan.replay.plots"): "matplotlib only when a plot is drawn",
}
"""Function-level imports of the package's modules outside ``cli/`` and ``bench/`` (whose
subcommand modules the command line imports to build its help), each with the start-up cost
it keeps away. Compiled kernels load through ``runtime.compiled.kernel_module`` instead."""


def function_level_imports() -> set[tuple[str, str]]:
    """(module, our module it imports inside a function) outside cli/ and bench/."""
    out: set[tuple[str, str]] = set()
    modules = {module_name(p) for p in PACKAGE.rglob("*.py")}
    for path in PACKAGE.rglob("*.py"):
        mod = module_name(path)
        if package_of(mod) in ("cli", "bench"):
            continue
        own = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        for fn in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if not isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                continue
            for node in ast.walk(fn):
                if isinstance(node, ast.ImportFrom):
                    base = node.module or ""
                    if node.level:
                        parts = own.split(".")
                        base = ".".join(parts[: len(parts) - node.level + 1] + ([base] if base else []))
                    if base.startswith("swarmplan"):
                        for a in node.names:  # ``from pkg import module`` names the module
                            sub = f"{base}.{a.name}"
                            out.add((mod, sub if sub in modules else base))
                elif isinstance(node, ast.Import):
                    out.update((mod, a.name) for a in node.names if a.name.startswith("swarmplan"))
    return out


def test_lazy_imports_only_where_start_up_needs_them() -> None:
    assert function_level_imports() - set(LAZY_IMPORTS) == set()


def test_the_product_speaks_of_itself() -> None:
    """No numbers of the work items that changed it (the words issue or stop and a number) and
    no words of how it was made, in the code, tests, docs, worlds or README."""
    import re

    words = re.compile(r"\b(?:issue|stop)[ -]\d|\bsessions?\b|\bissue's\b", re.I)
    root = PACKAGE.parent
    files = [root / "README.md", *root.glob("docs/*.md"), *root.glob("worlds/**/*.yaml")]
    files += [*PACKAGE.rglob("*.py"), *root.glob("tests/**/*.py")]
    found = [
        f"{p.relative_to(root)}:{k}: {line.strip()}"
        for p in files
        for k, line in enumerate(p.read_text(encoding="utf-8").splitlines(), 1)
        if words.search(line)
    ]
    assert found == []


def names_in_code(tree: ast.AST, module: str) -> tuple[set[str], set[str]]:
    """(modules imported, identifiers used) anywhere in ``tree`` (``if TYPE_CHECKING:`` blocks
    included): imports resolved to absolute names; identifiers are names, attributes,
    definitions, arguments, keywords and imported aliases (comments and strings are not code)."""
    imported: set[str] = set()
    idents: set[str] = set()
    package = module.rpartition(".")[0]
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            imported.update(a.name for a in node.names)
            idents.update(a.asname or a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[: len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            imported.add(base)
            imported.update(f"{base}.{a.name}" for a in node.names)
            idents.update(n for a in node.names for n in (a.name, a.asname) if n)
        elif isinstance(node, ast.Call) and (dynamic := dynamic_imports(node, {})):
            imported.update(dynamic)
        if isinstance(node, ast.Name):
            idents.add(node.id)
        elif isinstance(node, ast.Attribute):
            idents.add(node.attr)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            idents.add(node.name)
        elif isinstance(node, ast.arg):
            idents.add(node.arg)
        elif isinstance(node, ast.keyword) and node.arg:
            idents.add(node.arg)
    return imported, idents


def recorder_leaks(sim_dir: Path) -> list[str]:
    """Where a module under ``sim_dir`` imports ``swarmplan.io`` or names a recorder."""
    leaks = []
    for path in sorted(sim_dir.rglob("*.py")):
        mod = module_name(path) if path.is_relative_to(PACKAGE) else f"swarmplan.sim.{path.stem}"
        imported, idents = names_in_code(ast.parse(path.read_text(encoding="utf-8")), mod)
        leaks += [
            f"{path.name} imports {m}" for m in sorted(imported) if m.split(".")[:2] == ["swarmplan", "io"]
        ]
        leaks += [f"{path.name} names {n}" for n in sorted(idents) if "recorder" in n.lower()]
    return leaks


def test_the_simulation_knows_no_recorder() -> None:
    """sim/ steps the world and reports; the runner and its observers own the log."""
    assert recorder_leaks(PACKAGE / "sim") == []


def test_the_recorder_check_sees_imports_and_names_not_comments(tmp_path: Path) -> None:
    (tmp_path / "a.py").write_text("from swarmplan.io.recording import McapRecorder\n")
    (tmp_path / "b.py").write_text("from ..io import runner  # the runner\n")
    (tmp_path / "c.py").write_text("def step(self, rec):\n    self.recorder.write(rec)\n")
    (tmp_path / "d.py").write_text('"""No recorder here."""\n# recorder\nx = "McapRecorder"\n')
    assert recorder_leaks(tmp_path) == [
        "a.py imports swarmplan.io.recording",
        "a.py imports swarmplan.io.recording.McapRecorder",
        "a.py names McapRecorder",
        "b.py imports swarmplan.io",
        "b.py imports swarmplan.io.runner",
        "c.py names recorder",
    ]
