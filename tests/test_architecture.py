"""The shape of the house (docs/architecture.md), checked statically on the sources: no module
imports another module's private name, nobody edits ``sys.path``, the import graph has no cycle,
no bare index reads a packed layout outside kernels/layout.py, and source files and functions
stay short.

Each checker is a small function; the negative controls feed it a made-up offender.
"""
from __future__ import annotations

import ast
import importlib
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent
PACKAGES = ("esp_gym", "agents", "benchmarks")
#: Longest source file allowed in esp_gym/ [lines] ("~400": a little slack for a docstring).
MAX_LINES = 450


def sources(packages=PACKAGES):
    for pkg in packages:
        for path in sorted((ROOT / pkg).rglob("*.py")):
            if "__pycache__" not in path.parts:
                yield path


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def resolve(module: str, is_package: bool, node: ast.ImportFrom) -> str:
    """The absolute module an ``ImportFrom`` names."""
    if not node.level:
        return node.module or ""
    base = module.split(".")
    base = base if is_package else base[:-1]
    base = base[:len(base) - (node.level - 1)]
    return ".".join(base + ([node.module] if node.module else []))


def private_imports(module: str, is_package: bool, tree: ast.AST) -> list:
    """``from X import _name`` of a name private to another module (``__future__`` aside)."""
    bad = []
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom) and node.module != "__future__":
            for alias in node.names:
                if alias.name.startswith("_") and not alias.name.startswith("__"):
                    bad.append(f"{module}: from {resolve(module, is_package, node)} import {alias.name}")
    return bad


def imported(module: str, is_package: bool, node: ast.AST, known: set) -> set:
    """The modules an import statement ``node`` needs (none for another statement): ``from p
    import x`` the module p.x where that is one, else p."""
    if isinstance(node, ast.Import):
        return {a.name for a in node.names}
    if isinstance(node, ast.ImportFrom):
        target = resolve(module, is_package, node)
        return {f"{target}.{a.name}" if f"{target}.{a.name}" in known else target for a in node.names}
    return set()


def module_imports(module: str, is_package: bool, tree: ast.Module, known: set) -> set:
    """Project modules imported at module level (imports inside functions run later and
    cannot form an import-time cycle)."""
    out = set().union(*(imported(module, is_package, node, known) for node in tree.body))
    return {m for m in out if m in known and m != module}


def any_imports(module: str, is_package: bool, tree: ast.Module, known: set) -> set:
    """Project modules imported anywhere in the module, inside functions too (a deferred import
    still makes each module need the other), except under ``if TYPE_CHECKING:`` (annotations)."""
    out = set()
    pending = list(tree.body)
    while pending:
        node = pending.pop()
        if isinstance(node, ast.If) and ast.unparse(node.test) in ("TYPE_CHECKING", "typing.TYPE_CHECKING"):
            pending.extend(node.orelse)
            continue
        out |= imported(module, is_package, node, known)
        pending.extend(ast.iter_child_nodes(node))
    return {m for m in out if m in known and m != module}


def find_cycle(graph: dict):
    """One cycle of the directed graph ``{node: successors}`` as a list, or None."""
    state = {}
    stack = []

    def visit(v):
        state[v] = 1
        stack.append(v)
        for w in sorted(graph.get(v, ())):
            if state.get(w) == 1:
                return stack[stack.index(w):] + [w]
            if w not in state:
                found = visit(w)
                if found:
                    return found
        stack.pop()
        state[v] = 2
        return None

    for v in sorted(graph):
        if v not in state:
            found = visit(v)
            if found:
                return found
    return None


#: A bare index into one of the packed vectors (diagnostics, balances, reports, inputs,
#: observation, reward terms, task/action parameters) under the names the code gives them.
PACKED = re.compile(r"(?<![.\w])(out|acc|accc|result|report|stats|_stats|tp|ap|obs|inputs|terms|_terms|_result)"
                    r"\[(\.\.\., ?|:, ?)?\d+(:\d+)?\]")


#: Matches that index something else than a packed layout (docs/architecture.md lists them).
NOT_LAYOUTS = {
    "esp_gym/verify/mujoco_chain.py": ["out[0] = self.attachment_position()"],  # row 0 of a (K, 3) trajectory
    "esp_gym/verify/ode.py": ["return out[0] if Y.ndim == 1 else out"],  # the one row of a single state
}


def bare_layout_indexes(text: str) -> list:
    return [line.strip() for line in text.splitlines() if PACKED.search(line)]


def _parsed():
    for path in sources():
        module = module_name(path)
        yield path, module, path.name == "__init__.py", ast.parse(path.read_text(), str(path))


def kernel_imports(module: str, is_package: bool, tree: ast.AST) -> list:
    """Imports of ``esp_gym.kernels`` (anywhere in the module, deferred ones too)."""
    found = []
    for node in ast.walk(tree):
        names = [a.name for a in node.names] if isinstance(node, ast.Import) else \
            [resolve(module, is_package, node)] if isinstance(node, ast.ImportFrom) else []
        found += [f"{module}: {name}" for name in names if name == "esp_gym.kernels" or name.startswith("esp_gym.kernels.")]
    return found


def test_the_agents_read_the_layouts_from_their_public_face_not_from_the_kernels():
    """agents/ imports esp_gym.layouts (and esp_gym.compiled), never esp_gym.kernels."""
    bad = [line for path, module, is_package, tree in _parsed() if module.split(".")[0] == "agents"
           for line in kernel_imports(module, is_package, tree)]
    assert not bad, bad
    # negative controls: both forms of the import are found, the public face is not
    tree = ast.parse("import esp_gym.kernels.layout\nfrom esp_gym.kernels.env.arrays import ACTION\n"
                     "def f():\n    from esp_gym.kernels import jit\nfrom esp_gym.layouts import TARGET\n")
    assert kernel_imports("agents.x", False, tree) == [
        "agents.x: esp_gym.kernels.layout", "agents.x: esp_gym.kernels.env.arrays", "agents.x: esp_gym.kernels"]


def test_no_module_imports_a_private_name():
    bad = [b for _, m, pkg, tree in _parsed() for b in private_imports(m, pkg, tree)]
    assert bad == []
    # negative control
    tree = ast.parse("from ..physics.simulator import _hidden\n")
    assert private_imports("esp_gym.pendulum.env", False, tree) == [
        "esp_gym.pendulum.env: from esp_gym.physics.simulator import _hidden"]


def test_nobody_edits_sys_path():
    offenders = [str(p.relative_to(ROOT)) for p in list(sources()) + sorted((ROOT / "tests").glob("*.py"))
                 if re.search(r"sys\.path\.(insert|append)", p.read_text()) and p.name != "test_architecture.py"]
    assert offenders == []


#: NumPy's transcendental ufuncs, whose code path is the processor's (SVML on AVX-512, the C
#: library elsewhere: agents/baselines/libm.py); the kernels' calls compile to the C library's.
NUMPY_TRANSCENDENTAL = re.compile(r"\bnp\.(sin|cos|tan|arcsin|arccos|arctan|arctan2|sinh|cosh|tanh|arcsinh|arccosh|"
                                  r"arctanh|exp|exp2|expm1|log|log2|log10|log1p|power|cbrt)\(")


def numpy_transcendentals(text: str) -> list:
    return [line.strip() for line in text.splitlines() if NUMPY_TRANSCENDENTAL.search(line.split("#")[0])]


def test_the_episode_path_calls_no_numpy_transcendental():
    """The environments and the agents (not the compiled kernels, the verification rigs or the
    figures) compute sin, exp and their kin with the C library, so an episode is the same bits on
    every x86-64 processor; a NumPy call is found (the negative control)."""
    exempt = ("esp_gym/kernels/", "esp_gym/verify/", "esp_gym/viz/", "agents/task_figures.py")
    offenders = {str(p.relative_to(ROOT)): numpy_transcendentals(p.read_text()) for p in sources(("esp_gym", "agents"))
                 if not str(p.relative_to(ROOT)).startswith(exempt)}
    assert {path: lines for path, lines in offenders.items() if lines} == {}
    assert numpy_transcendentals("    c = np.cos(w * t)  # a reference") == ["c = np.cos(w * t)  # a reference"]
    assert numpy_transcendentals("    c = math.cos(w)  # np.cos(w) differs by processor") == []


def test_the_import_graph_has_no_cycle():
    parsed = list(_parsed())
    known = {m for _, m, _, _ in parsed}
    graph = {m: module_imports(m, pkg, tree, known) for _, m, pkg, tree in parsed}
    assert find_cycle(graph) is None, find_cycle(graph)
    # negative control: agents.controllers <-> agents.evaluate, as it once was
    assert find_cycle({"a.x": {"a.y"}, "a.y": {"a.x"}}) == ["a.x", "a.y", "a.x"]


def test_no_deferred_import_hides_a_cycle():
    """Imports inside functions count too: a circle they hide (params -> stepsize -> model ->
    params, agents.zoo <-> benchmarks.quote, as they once were) still ties the modules together."""
    parsed = list(_parsed())
    known = {m for _, m, _, _ in parsed}
    graph = {m: any_imports(m, pkg, tree, known) for _, m, pkg, tree in parsed}
    assert find_cycle(graph) is None, find_cycle(graph)
    # negative controls: a function's import is found; one under TYPE_CHECKING is not
    source = ast.parse("from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from a import y\n"
                       "def f():\n    from a import x\n")
    assert any_imports("b", False, source, {"a.x", "a.y"}) == {"a.x"}
    assert module_imports("b", False, source, {"a.x", "a.y"}) == set()


#: What each lower package may not import (deferred imports too): a scene is validated without the
#: physics, and the physics runs without an environment (docs/architecture.md, "The layers").
BELOW = {"esp_gym.scene": ("esp_gym.physics", "esp_gym.pendulum", "esp_gym.team", "esp_gym.viz", "esp_gym.verify",
                           "esp_gym.errors", "esp_gym.zoo", "esp_gym.cli", "esp_gym.precompile"),
         "esp_gym.physics": ("esp_gym.pendulum", "esp_gym.team", "esp_gym.viz", "esp_gym.verify", "esp_gym.zoo",
                             "esp_gym.cli", "esp_gym.precompile")}


def layer_violations(graph: dict) -> list:
    """``module -> imported`` pairs of ``graph`` where a package of :data:`BELOW` imports what lies above it."""
    return sorted(f"{m} -> {i}" for m, imports in graph.items() for below, above in BELOW.items()
                  if m == below or m.startswith(below + ".")
                  for i in imports if any(i == a or i.startswith(a + ".") for a in above))


def test_the_scene_and_the_physics_import_nothing_above_them():
    parsed = list(_parsed())
    known = {m for _, m, _, _ in parsed}
    graph = {m: any_imports(m, pkg, tree, known) for _, m, pkg, tree in parsed}
    assert layer_violations(graph) == []
    # negative controls: the drone's face reading the env's setup, a scene asking the simulator
    assert layer_violations({"esp_gym.physics.drone": {"esp_gym.pendulum.env_setup", "esp_gym.physics.state"},
                             "esp_gym.scene.stepsize": {"esp_gym.physics.simulator"}}) == [
        "esp_gym.physics.drone -> esp_gym.pendulum.env_setup", "esp_gym.scene.stepsize -> esp_gym.physics.simulator"]


def test_packed_layouts_are_read_by_name_outside_their_module():
    layout = ROOT / "esp_gym" / "kernels" / "layout.py"
    found = {str(p.relative_to(ROOT)): bare_layout_indexes(p.read_text())
             for p in list(sources()) + sorted((ROOT / "tests").glob("*.py"))
             if p not in (layout, Path(__file__).resolve())}
    assert {k: v for k, v in found.items() if v and v != NOT_LAYOUTS.get(k)} == {}
    # negative controls: the patterns the layouts replaced
    assert bare_layout_indexes("e = out[4]\nv = obs[..., 9:12]\nx = tp[6]\nok = acc[2:5]") == [
        "e = out[4]", "v = obs[..., 9:12]", "x = tp[6]", "ok = acc[2:5]"]


@pytest.mark.parametrize("path", [p for p in sources(("esp_gym",))], ids=lambda p: str(p.relative_to(ROOT)))
def test_source_files_are_short(path):
    assert len(path.read_text().splitlines()) <= MAX_LINES


#: Longest function allowed [lines, its signature to its last line].
MAX_FUNCTION_LINES = 60
#: Functions longer than that which stay whole, and why.
LONG_BY_DESIGN = {
    "esp_gym/verify/ode_kernels.py:ode_rhs": "the verification's right-hand side: the continuous equations of "
                                      "docs/physics.md in one place, read against them line by line",
}
#: Functions longer than that, to split by stage or role: none left (issue 55, item 6). The set may
#: only shrink (a listed function that became short fails until it leaves the list).
TO_SPLIT = set()


def long_functions(source: str, limit: int = MAX_FUNCTION_LINES) -> dict:
    """Name -> lines of every function (methods and nested ones too) of ``source`` longer than ``limit``."""
    return {node.name: node.end_lineno - node.lineno + 1 for node in ast.walk(ast.parse(source))
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)) and node.end_lineno - node.lineno >= limit}


def test_functions_are_short_or_listed_with_a_reason():
    found = {f"{path.relative_to(ROOT).as_posix()}:{name}": lines for path in sources()
             for name, lines in long_functions(path.read_text()).items()}
    unlisted = {name: lines for name, lines in found.items() if name not in LONG_BY_DESIGN and name not in TO_SPLIT}
    assert not unlisted, f"functions over {MAX_FUNCTION_LINES} lines: split them by stage or role: {unlisted}"
    short_now = (set(LONG_BY_DESIGN) | TO_SPLIT) - set(found)
    assert not short_now, f"no longer over {MAX_FUNCTION_LINES} lines: take them off the lists: {sorted(short_now)}"
    # negative controls: a long function and a long method are found, a short one is not
    body = "".join(f"    x{i} = {i}\n" for i in range(MAX_FUNCTION_LINES))
    assert long_functions(f"def f():\n{body}") == {"f": MAX_FUNCTION_LINES + 1}
    assert long_functions(f"class C:\n    def g(self):\n    {body.replace(chr(10), chr(10) + '    ')}") == {
        "g": MAX_FUNCTION_LINES + 1}
    assert long_functions("def h():\n    return 1\n") == {}


def test_the_environments_do_not_import_torch():
    """The env and the Gymnasium vector env (what ``gym.make``/``gym.make_vec`` import) load
    without Stable-Baselines3 and torch: importing them cost 1.4 s of a 2.3 s warm start."""
    code = ("import sys, esp_gym, esp_gym.pendulum.env, esp_gym.pendulum.vector; "
            "print(sorted(m for m in ('torch', 'stable_baselines3') if m in sys.modules))")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert done.stdout.strip() == "[]"
    # negative control: the SB3 vector env does bring them in
    code = code.replace("esp_gym.pendulum.vector;", "esp_gym.pendulum.sb3_vector;")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, check=True)
    assert done.stdout.strip() == "['stable_baselines3', 'torch']"


#: The packages whose every module docs/architecture.md names.
DOCUMENTED = ("esp_gym", "agents", "benchmarks")


def named_paths(doc: str) -> set:
    """The ``.py`` paths ``doc`` names, as written (``kernels/x.py`` and ``viz/x.py`` are short for
    ``esp_gym/kernels/x.py`` and ``esp_gym/viz/x.py``)."""
    return set(re.findall(r"[\w./]+\.py\b", doc))


def repository_file(path: str):
    """The repository file a named path means, or None."""
    for candidate in (path, f"esp_gym/{path}"):
        if (ROOT / candidate).is_file():
            return candidate
    return None


def modules_not_named(doc: str) -> list:
    """The modules of DOCUMENTED (packages' __init__ aside) that ``doc`` does not name by path."""
    named = {repository_file(path) for path in named_paths(doc)}
    return sorted(str(p.relative_to(ROOT)) for package in DOCUMENTED for p in (ROOT / package).rglob("*.py")
                  if p.name != "__init__.py" and "__pycache__" not in p.parts and "out" not in p.parts
                  and str(p.relative_to(ROOT)) not in named)


def test_the_architecture_doc_names_every_module_and_only_modules_that_exist():
    doc = (ROOT / "docs" / "architecture.md").read_text()
    assert modules_not_named(doc) == []
    assert sorted(path for path in named_paths(doc) if repository_file(path) is None) == []
    # negative controls: a doc without a module's path, or naming a module that does not exist
    assert modules_not_named(doc.replace("`agents/baselines/gain_search.py`", "tune")) == ["agents/baselines/gain_search.py"]
    assert modules_not_named(doc.replace("kernels/step/switch.py", "switch.py")) == ["esp_gym/kernels/step/switch.py"]
    assert [path for path in named_paths(doc + " `esp_gym/kernels/gone.py`") if repository_file(path) is None] == [
        "esp_gym/kernels/gone.py"]


#: Each layout module's offset prefixes and the layouts they index (kernels/layout.py and the
#: owners' modules): an alias PREFIX_FIELD is the offset of FIELD in one of them.
OFFSET_PREFIXES = {
    "esp_gym.kernels.layout": {"D_": ("DIAG",), "B_": ("BALANCE",), "WN_": ("WINCH",), "SD_": ("STEP_DIAG",),
                               "IN_": ("INPUTS",), "R_": ("REPORT",)},
    "esp_gym.kernels.env.arrays": {"A_": ("ACTION", "WINCH_ACTION"), "AP_": ("ACTION_PARAMS",), "T_": ("TARGET",),
                                   "O_": ("OBSERVATION", "WINCH_OBSERVATION"), "SN_": ("SENSORS",),
                                   "RW_": ("REWARD",), "TP_": ("TASK_PARAMS",), "F_": ("FEATURES",)},
    "esp_gym.kernels.step.disturbance": {"DP_": ("DISTURBANCE_PARAMS",), "DS_": ("DISTURBANCE",), "DR_": ("DRAWS",)},
    "esp_gym.kernels.drone.quadrotor": {"Q_": ("DRONE",), "QD_": ("DRONE_DIAG",)},
    "esp_gym.kernels.drone.env": {"QA_": ("DRONE_ACTION_PARAMS",), "QS_": ("DRONE_SENSORS",)},
    "esp_gym.kernels.env.recording": {"S_": ("SAMPLE_HEAD",), "SW_": ("SAMPLE_WINCH",), "SI_": ("SAMPLE_INPUTS",),
                                  "SB_": ("SAMPLE_BALANCES",)},
}


def misnamed_offsets(namespace: dict, prefixes: dict) -> list:
    """The integer aliases of ``namespace`` with one of ``prefixes`` that are not PREFIX + the upper
    case of a field of the prefix's layouts, holding that field's offset."""
    out = []
    for name, value in namespace.items():
        if not name.isupper() or isinstance(value, bool) or not isinstance(value, int):
            continue
        prefix = max((p for p in prefixes if name.startswith(p)), key=len, default=None)
        if prefix is None:
            continue
        layouts = [namespace[layout] for layout in prefixes[prefix]]
        if not any(prefix + field.upper() == name and layout.start(field) == value
                   for layout in layouts for field in layout.names):
            out.append(name)
    return out


@pytest.mark.parametrize("module", sorted(OFFSET_PREFIXES))
def test_offset_names_follow_from_the_fields(module):
    """Every offset alias is its layout's field name in upper case after the layout's prefix, and
    holds that field's offset: O_LOAD_POSITION_ERROR = OBSERVATION.start("load_position_error")."""
    namespace = vars(importlib.import_module(module))
    assert misnamed_offsets(namespace, OFFSET_PREFIXES[module]) == []
    assert sum(1 for name in namespace if any(name.startswith(p) for p in OFFSET_PREFIXES[module])) >= 3


def test_a_misnamed_offset_is_found():
    """Negative control: an alias named after something else, and one holding another field's
    offset, are both found; a right one is not."""
    from esp_gym.kernels.env.arrays import OBSERVATION

    namespace = {"OBSERVATION": OBSERVATION, "O_LOAD_POSITION_ERROR": OBSERVATION.start("load_position_error"),
                 "O_PIVOT_ERROR": OBSERVATION.start("pivot_position_error"),
                 "O_LOAD_VELOCITY": OBSERVATION.start("pivot_velocity")}
    assert misnamed_offsets(namespace, {"O_": ("OBSERVATION",)}) == ["O_PIVOT_ERROR", "O_LOAD_VELOCITY"]
