"""The static import graph of ``dem`` and ``hmm``: no cycle, and the layering holds.

Every ``import`` statement counts, at module level or inside a function (a lazy import
is still a dependency), with relative imports resolved against the importing module.
An edge goes to the module an import names: ``from .shapes.table import ShapeTable``
is an edge to ``dem.shapes.table``, ``from . import rotation`` one to ``dem.rotation``.
The asserted rules: no import cycle; ``dem`` never imports ``hmm``; ``mpi4py`` is
imported in ``hmm/farm.py`` only, and there only inside functions (the suite runs
serially through the same code); the kernels' status codes are defined in
``dem/status.py`` only, the shape kinds in ``dem/shapes/kinds.py`` only; no module is
longer than 600 lines but those listed in :data:`LONG_MODULES` with their reason; no
function is longer than 100 lines and no compiled kernel takes more than 20 arguments
but those listed in :data:`LONG_FUNCTIONS` and :data:`MANY_ARGUMENTS` with theirs;
every function is compiled through ``dem._jit``.
"""

import ast
from collections import deque
from pathlib import Path

from dem.shapes import Shape
from dem.status import Status

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("dem", "hmm")


def module_files(root=ROOT, packages=PACKAGES):
    """``{dotted module name: path}`` of every Python file of ``packages`` under ``root``."""
    out = {}
    for package in packages:
        for path in sorted((root / package).rglob("*.py")):
            parts = path.relative_to(root).with_suffix("").parts
            if parts[-1] == "__init__":
                parts = parts[:-1]
            out[".".join(parts)] = path
    return out


def imports_of(name, source, known, is_package=False):
    """``(target, line, lazy)`` for every import in ``source``, the text of module ``name``.

    ``known`` is the set of module names of the project: ``from a import b`` names the
    module ``a.b`` when that is one of them, else the module ``a``. ``lazy`` is true for
    an import inside a function body.
    """
    tree = ast.parse(source)
    lazy_nodes = set()
    for fn in ast.walk(tree):
        if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            lazy_nodes.update(id(node) for node in ast.walk(fn) if node is not fn)
    found = []
    for node in ast.walk(tree):
        lazy = id(node) in lazy_nodes
        if isinstance(node, ast.Import):
            found += [(alias.name, node.lineno, lazy) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = name.split(".") if is_package else name.split(".")[:-1]
                if node.level - 1 > len(base) - 1:
                    raise ValueError(f"{name}:{node.lineno}: relative import beyond the top")
                base = base[:len(base) - (node.level - 1)]
                base = ".".join(base + ([node.module] if node.module else []))
            else:
                base = node.module
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                found.append((sub if sub in known else base, node.lineno, lazy))
    return found


def import_graph(files):
    """``{module: {imported project module: first line}}`` over the modules of ``files``."""
    known = set(files)
    graph = {}
    for name, path in files.items():
        edges = {}
        for target, line, _ in imports_of(name, path.read_text(), known,
                                          path.name == "__init__.py"):
            if target in known and target != name:
                edges.setdefault(target, line)
        graph[name] = edges
    return graph


def find_cycles(graph):
    """One cycle ``[m0, m1, ..., m0]`` for each strongly connected component that has one.

    Tarjan's algorithm (iterative) gives the components; within each, a breadth-first
    search from its smallest member back to itself gives a shortest cycle through it.
    """
    index, low, on_stack, stack, components = {}, {}, set(), [], []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph.get(child, ())))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                parent = work[-1][0]
                low[parent] = min(low[parent], low[node])
            if low[node] == index[node]:
                component = set()
                while True:
                    member = stack.pop()
                    on_stack.discard(member)
                    component.add(member)
                    if member == node:
                        break
                if len(component) > 1 or node in graph.get(node, ()):
                    components.append(component)
    cycles = []
    for component in components:
        start = min(component)
        parent, queue, last = {start: None}, deque([start]), None
        while last is None:
            node = queue.popleft()
            for child in sorted(graph[node]):
                if child == start:
                    last = node
                    break
                if child in component and child not in parent:
                    parent[child] = node
                    queue.append(child)
        path = [start]
        while last is not None:
            path.append(last)
            last = parent[last]
        cycles.append(path[::-1])
    return sorted(cycles)


def describe(cycle, graph, files):
    """``a (a.py:12) -> b (b.py:40) -> a``: each step with the line of its import."""
    steps = [f"{a} ({files[a].relative_to(ROOT)}:{graph[a][b]})"
             for a, b in zip(cycle, cycle[1:], strict=False)]
    return " -> ".join(steps + [cycle[-1]])


FILES = module_files()
GRAPH = import_graph(FILES)


def test_the_graph_sees_every_kind_of_import():
    known = {"p", "p.a", "p.b", "p.sub", "p.sub.c", "p.sub.d"}
    source = ("import p.a\n"
              "import numpy.linalg as la\n"
              "from . import c\n"
              "from . import thing\n"
              "from ..b import x\n"
              "from .. import a\n"
              "def f():\n"
              "    from p.sub.c import y\n")
    found = imports_of("p.sub.d", source, known)
    assert [(target, lazy) for target, _, lazy in found] == [
        ("p.a", False), ("numpy.linalg", False), ("p.sub.c", False), ("p.sub", False),
        ("p.b", False), ("p.a", False), ("p.sub.c", True)]
    package = imports_of("p.sub", "from . import c\nfrom .d import z\n", known,
                         is_package=True)
    assert [target for target, _, _ in package] == ["p.sub.c", "p.sub.d"]
    assert len(FILES) > 50, "the scan found too few modules"
    assert "dem.shapes" in GRAPH["dem.state"] and "dem.state" in GRAPH["dem"]


def test_cycle_finder_reports_a_cycle():
    graph = {"a": {"b": 1}, "b": {"c": 2}, "c": {"a": 3, "d": 4}, "d": {}, "e": {"e": 5}}
    assert find_cycles(graph) == [["a", "b", "c", "a"], ["e", "e"]]
    assert find_cycles({"a": {"b": 1}, "b": {}, "c": {"a": 1, "b": 2}}) == []


def test_no_import_cycle():
    cycles = find_cycles(GRAPH)
    assert not cycles, "import cycles:\n" + "\n".join(
        describe(c, GRAPH, FILES) for c in cycles)


def test_dem_never_imports_hmm():
    bad = [f"{FILES[name].relative_to(ROOT)}:{line} imports {target}"
           for name in FILES if name.split(".")[0] == "dem"
           for target, line, _ in imports_of(name, FILES[name].read_text(), set(FILES),
                                             FILES[name].name == "__init__.py")
           if target.split(".")[0] == "hmm"]
    assert not bad, "\n".join(bad)


def test_mpi4py_only_in_the_farm_and_lazily():
    where = [(name, line, lazy) for name in FILES
             for target, line, lazy in imports_of(name, FILES[name].read_text(), set(FILES),
                                                  FILES[name].name == "__init__.py")
             if target.split(".")[0] == "mpi4py"]
    assert where, "no mpi4py import found at all: the scan is broken"
    elsewhere = [f"{FILES[n].relative_to(ROOT)}:{line}" for n, line, _ in where
                 if n != "hmm.farm"]
    assert not elsewhere, f"mpi4py imported outside hmm/farm.py: {elsewhere}"
    eager = [line for _, line, lazy in where if not lazy]
    assert not eager, f"hmm/farm.py imports mpi4py at module level, lines {eager}"


def _bound_pairs(target, value):
    """``(target name node, value node or None)`` of one assignment target: a tuple
    target takes its values element by element when the value is a tuple of the same
    length, else ``None`` each."""
    if not isinstance(target, ast.Tuple):
        return [(target, value)]
    if isinstance(value, ast.Tuple) and len(value.elts) == len(target.elts):
        return list(zip(target.elts, value.elts, strict=True))
    return [(e, None) for e in target.elts]


def module_bindings(path, names, int_literals=False):
    """``(line, name)`` for each module-level assignment in ``path`` that binds one of
    ``names``; with ``int_literals``, only those binding it to an integer literal
    (``BOX = 2``, ``SPHERE, PLANE = 0, 1``)."""
    found = []
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Assign):
            targets, value = node.targets, node.value
        elif isinstance(node, ast.AnnAssign):
            targets, value = [node.target], node.value
        else:
            continue
        for target in targets:
            for name, bound in _bound_pairs(target, value):
                if not (isinstance(name, ast.Name) and name.id in names):
                    continue
                if int_literals and not (isinstance(bound, ast.Constant)
                                         and type(bound.value) is int):
                    continue
                found.append((node.lineno, name.id))
    return found


def test_the_binding_scan_sees_codes_written_as_numbers(tmp_path):
    path = tmp_path / "m.py"
    path.write_text("BOX = 2\nSPHERE, PLANE = 0, 1\nCUSTOM = int(K.CUSTOM)\n"
                    "POLYGON = 0.08\ndef f():\n    BOX = 3\n")
    names = {"BOX", "SPHERE", "PLANE", "CUSTOM", "POLYGON"}
    assert module_bindings(path, names, int_literals=True) == [
        (1, "BOX"), (2, "SPHERE"), (2, "PLANE")]
    assert [n for _, n in module_bindings(path, names)] == [
        "BOX", "SPHERE", "PLANE", "CUSTOM", "POLYGON"]


def test_status_codes_are_defined_once():
    """No module but ``dem.status`` binds a status name to a value of its own."""
    names = {member.name for member in Status} | {"FAILED"}
    found = [f"{path.relative_to(ROOT)}:{line} {name}" for mod, path in FILES.items()
             if mod != "dem.status" for line, name in module_bindings(path, names)]
    assert not found, "status codes defined outside dem/status.py: " + ", ".join(found)


def test_shape_kinds_are_defined_once():
    """No module but ``dem.shapes.kinds`` writes a shape kind's code as a number (a
    ``BOX`` that means a length, as in the demo, is not a code)."""
    names = {member.name for member in Shape}
    found = [f"{path.relative_to(ROOT)}:{line} {name}" for mod, path in FILES.items()
             if mod != "dem.shapes.kinds"
             for line, name in module_bindings(path, names, int_literals=True)]
    assert not found, "shape kinds defined outside dem/shapes/kinds.py: " + ", ".join(found)


#: numba's entry points that compile a function
NUMBA_COMPILERS = ("njit", "jit", "cfunc", "vectorize", "guvectorize", "stencil",
                   "generated_jit")


def compile_paths(files, root=ROOT, owner="dem/_jit.py"):
    """Where a module other than ``owner`` reaches one of numba's compilers: an
    attribute ``numba.njit`` (decorator or call) or ``from numba import njit``."""
    found = []
    for path in files.values():
        rel = path.relative_to(root).as_posix()
        if rel == owner:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            if (isinstance(node, ast.Attribute) and node.attr in NUMBA_COMPILERS
                    and isinstance(node.value, ast.Name) and node.value.id == "numba"):
                found.append(f"{rel}:{node.lineno} numba.{node.attr}")
            elif isinstance(node, ast.ImportFrom) and (node.module or "").startswith("numba"):
                found += [f"{rel}:{node.lineno} from {node.module} import {a.name}"
                          for a in node.names if a.name in NUMBA_COMPILERS]
    return sorted(found)


def test_the_compile_path_check_sees_numba_compilers(tmp_path):
    (tmp_path / "a.py").write_text(
        "import numba\n@numba.njit\ndef f(x):\n    return x\n"
        "g = numba.jit(cache=True)(f)\nok = numba.prange\n")
    (tmp_path / "b.py").write_text("from numba import cfunc, types\n")
    (tmp_path / "_jit.py").write_text("import numba\nk = numba.njit\n")
    files = {n: tmp_path / f"{n}.py" for n in ("a", "b", "_jit")}
    assert compile_paths(files, root=tmp_path, owner="_jit.py") == [
        "a.py:2 numba.njit", "a.py:5 numba.jit", "b.py:1 from numba import cfunc"]


def test_every_compile_path_goes_through_dem_jit():
    """``dem._jit`` owns the compile options (error model, cache, inlining, the prange
    passes): a kernel compiled elsewhere would miss them and their documentation."""
    found = compile_paths(FILES)
    assert not found, "numba compiled outside dem/_jit.py: " + ", ".join(found)


#: the most lines a module of ``dem`` or ``hmm`` may have
MAX_LINES = 600
#: modules allowed above :data:`MAX_LINES`, each with its reason
LONG_MODULES = {}


def long_modules(files, limit=MAX_LINES, root=ROOT):
    """``{path relative to root: line count}`` of the files of ``files`` above ``limit``."""
    counts = {path.relative_to(root).as_posix(): len(path.read_text().splitlines())
              for path in files.values()}
    return {path: n for path, n in counts.items() if n > limit}


def test_the_line_count_sees_a_long_module(tmp_path):
    (tmp_path / "short.py").write_text("x = 1\n" * 3)
    (tmp_path / "long.py").write_text("x = 1\n" * 4)
    files = {"short": tmp_path / "short.py", "long": tmp_path / "long.py"}
    assert long_modules(files, limit=3, root=tmp_path) == {"long.py": 4}
    assert long_modules(files, limit=4, root=tmp_path) == {}


def test_no_module_over_600_lines():
    long = long_modules(FILES)
    unexplained = {path: n for path, n in long.items() if path not in LONG_MODULES}
    assert not unexplained, (f"modules over {MAX_LINES} lines (split them, or list one "
                             f"with its reason in LONG_MODULES): {unexplained}")
    stale = sorted(set(LONG_MODULES) - set(long))
    assert not stale, f"listed in LONG_MODULES but no longer over {MAX_LINES} lines: {stale}"


#: the most lines (``def`` to its end, docstring included) a function may have
MAX_FUNCTION_LINES = 100
#: the most arguments a compiled kernel may take
MAX_KERNEL_ARGS = 20
_LOOP = ("the time loop: one compiled function per step phase would put each phase's "
         "arrays through a call, and the step's order is clearest read in one place "
         "(docs/architecture.md, One step, in order)")
#: functions allowed above :data:`MAX_FUNCTION_LINES`, each with its reason
LONG_FUNCTIONS = {
    "dem/contact/loops.py:stepper": "the factory of the sphere time loop; " + _LOOP,
    "dem/contact/loops.py:stepper.run_steps": "the sphere time loop; " + _LOOP,
    "dem/contact/shape_loop.py:shape_stepper": "the factory of the shape time loop; " + _LOOP,
    "dem/contact/shape_loop.py:shape_stepper.run_shape_steps": "the shape time loop; " + _LOOP,
}
_PER_CONTACT = ("runs once per contact and step, so it takes only the arrays it uses: read "
                "through the state bundles instead, it made the {} "
                "(docs/performance.md, \"The force kernels and the bundles\")")
#: compiled kernels allowed above :data:`MAX_KERNEL_ARGS`, each with its reason (the
#: others take state bundles where they read many arrays: docs/architecture.md, "What a
#: compiled loop takes")
MANY_ARGUMENTS = {
    "dem/contact/sphere_contacts.py:_sphere_pair": _PER_CONTACT.format(
        "2D periodic RVE's stepping 24 % slower (inlined into the sphere loop)"),
    "dem/contact/shape_contacts.py:pair_force": _PER_CONTACT.format(
        "2D shape scene 20 % slower, with wall_force (a real call from the shape loop)"),
    "dem/contact/shape_contacts.py:wall_force": _PER_CONTACT.format(
        "2D shape scene 20 % slower, with pair_force (a real call from the shape loop)"),
}


_COMPILERS = ("kernel", "njit", "jit")


def _compiles(deco):
    """Whether a decorator compiles its function: ``kernel``, ``njit`` or ``jit``, bare,
    called or reached as an attribute (``numba.njit``)."""
    target = deco.func if isinstance(deco, ast.Call) else deco
    name = target.attr if isinstance(target, ast.Attribute) else getattr(target, "id", "")
    return name in _COMPILERS


def _is_kernel(node):
    """Whether a function is compiled: decorated with ``kernel``, ``njit`` or ``jit``."""
    return any(_compiles(deco) for deco in node.decorator_list)


def oversized_functions(files, max_lines=MAX_FUNCTION_LINES, max_args=MAX_KERNEL_ARGS,
                        root=ROOT):
    """``({"path:qualname": lines}, {"path:qualname": arguments})``: the functions of
    ``files`` longer than ``max_lines`` and the kernels with more than ``max_args``
    arguments."""
    long, many = {}, {}
    for path in files.values():
        rel = path.relative_to(root).as_posix()
        stack = [(node, "") for node in ast.parse(path.read_text()).body]
        while stack:
            node, prefix = stack.pop()
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
                name = prefix + node.name
                stack.extend((child, name + ".") for child in node.body)
                if isinstance(node, ast.ClassDef):
                    continue
                lines = node.end_lineno - node.lineno + 1
                if lines > max_lines:
                    long[f"{rel}:{name}"] = lines
                n_args = len(node.args.posonlyargs) + len(node.args.args)
                if _is_kernel(node) and n_args > max_args:
                    many[f"{rel}:{name}"] = n_args
    return long, many


def test_the_size_check_sees_long_functions_and_kernels(tmp_path):
    body = "    x = 1\n" * 3
    (tmp_path / "m.py").write_text(
        "@kernel\ndef k(a, b, c):\n" + body + "def plain(a, b, c):\n" + body
        + "class C:\n    def meth(self):\n" + "        x = 1\n" * 4)
    files = {"m": tmp_path / "m.py"}
    long, many = oversized_functions(files, max_lines=4, max_args=2, root=tmp_path)
    assert long == {"m.py:C.meth": 5}
    assert many == {"m.py:k": 3}  # only compiled kernels count arguments
    assert oversized_functions(files, max_lines=5, max_args=3, root=tmp_path) == ({}, {})


def test_no_function_over_100_lines_and_no_kernel_over_20_arguments():
    long, many = oversized_functions(FILES)
    unexplained = ({k: n for k, n in long.items() if k not in LONG_FUNCTIONS},
                   {k: n for k, n in many.items() if k not in MANY_ARGUMENTS})
    assert unexplained == ({}, {}), (
        f"functions over {MAX_FUNCTION_LINES} lines, kernels over {MAX_KERNEL_ARGS} "
        "arguments (split them, or list one with its reason in LONG_FUNCTIONS or "
        f"MANY_ARGUMENTS): {unexplained}")
    stale = sorted(set(LONG_FUNCTIONS) - set(long)) + sorted(set(MANY_ARGUMENTS) - set(many))
    assert not stale, f"listed but no longer over the limits: {stale}"


def _is_inline(node):
    """Whether a function is a kernel inlined into its callers (``kernel(inline=True)``,
    ``njit(inline="always")``)."""
    return any(isinstance(deco, ast.Call) and _compiles(deco)
               and any(kw.arg == "inline" and isinstance(kw.value, ast.Constant)
                       and kw.value.value in (True, "always") for kw in deco.keywords)
               for deco in node.decorator_list)


def _is_prange(node):
    """Whether a ``for`` loop runs over ``prange(...)`` or ``numba.prange(...)``."""
    call = node.iter
    if not isinstance(call, ast.Call):
        return False
    f = call.func
    return (f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", "")) == "prange"


def _targets(node):
    """The assignment targets of ``node`` (tuples unpacked)."""
    if isinstance(node, ast.Assign):
        todo = list(node.targets)
    elif isinstance(node, (ast.AugAssign, ast.AnnAssign)):
        todo = [node.target]
    else:
        return []
    out = []
    while todo:
        t = todo.pop()
        if isinstance(t, (ast.Tuple, ast.List)):
            todo.extend(t.elts)
        else:
            out.append(t)
    return out


def _bound_from_attributes(fn):
    """Names that ``fn`` binds to an attribute (``f = p.f``, ``a, b = p.a, p.b``)."""
    names = set()
    for node in ast.walk(fn):
        if not isinstance(node, ast.Assign):
            continue
        for t in node.targets:
            pairs = [(t, node.value)]
            if isinstance(t, ast.Tuple) and isinstance(node.value, ast.Tuple):
                pairs = list(zip(t.elts, node.value.elts, strict=False))
            names.update(a.id for a, v in pairs
                         if isinstance(a, ast.Name) and isinstance(v, ast.Attribute))
    return names


def _attribute_writes(scope, bound):
    """Lines in ``scope`` that write into an array reached through an attribute:
    ``p.f[k] = x``, or ``f[k] = x`` with ``f`` in ``bound`` (bound to an attribute)."""
    lines = set()
    for stmt in ast.walk(scope):
        for t in _targets(stmt):
            while isinstance(t, ast.Subscript) and isinstance(t.value, ast.Subscript):
                t = t.value
            if isinstance(t, ast.Subscript) and (
                    isinstance(t.value, ast.Attribute)
                    or (isinstance(t.value, ast.Name) and t.value.id in bound)):
                lines.add(stmt.lineno)
    return lines


def _called_names(scope):
    """Names of the functions called in ``scope`` (``f(...)``, ``m.f(...)``)."""
    names = set()
    for node in ast.walk(scope):
        if isinstance(node, ast.Call):
            f = node.func
            names.add(f.attr if isinstance(f, ast.Attribute) else getattr(f, "id", ""))
    return names


def bundle_writes(files, root=ROOT):
    """``["path:qualname:line"]``: writes into an array reached through an attribute
    (``p.f[k] = x``, or ``f[k] = x`` after ``f = p.f``) in the body of a ``prange``
    loop, or in an inlined kernel that such a body calls (directly or through other
    inlined kernels; a real call ends the search, being compiled on its own).

    Numba drops such writes in a parallel loop without a word when ``p`` is a
    NamedTuple (numba issues 5872, 7135 and 10338, open in 0.68): the loop runs and the
    array keeps its old values. Reads are correct, so the kernels of the parallel loops
    read from bundles and take the arrays they write as arguments of their own.
    """
    functions = []  # (rel, qualname, node)
    for path in files.values():
        rel = path.relative_to(root).as_posix()
        stack = [(node, "") for node in ast.parse(path.read_text()).body]
        while stack:
            node, prefix = stack.pop()
            if isinstance(node, ast.ClassDef):
                stack.extend((child, prefix + node.name + ".") for child in node.body)
            elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                functions.append((rel, prefix + node.name, node))
                stack.extend((child, prefix + node.name + ".") for child in node.body)
    inline = {}
    for rel, name, node in functions:
        if _is_inline(node):
            inline.setdefault(node.name, []).append((rel, name, node))
    found, seen = set(), set()
    for rel, name, node in functions:
        bound = _bound_from_attributes(node)
        todo = []
        for loop in ast.walk(node):
            if isinstance(loop, ast.For) and _is_prange(loop):
                found.update(f"{rel}:{name}:{line}" for line in _attribute_writes(loop, bound))
                todo += [c for c in _called_names(loop) if c in inline]
        while todo:
            callee = todo.pop()
            if callee in seen:
                continue
            seen.add(callee)
            for crel, cname, cnode in inline[callee]:
                found.update(f"{crel}:{cname}:{line}" for line in
                             _attribute_writes(cnode, _bound_from_attributes(cnode)))
                todo += [c for c in _called_names(cnode) if c in inline]
    return sorted(found, key=lambda f: (f.rsplit(":", 1)[0], int(f.rsplit(":", 1)[1])))


def test_the_bundle_write_check_sees_writes_through_attributes(tmp_path):
    (tmp_path / "m.py").write_text(
        "@kernel(inline=True)\ndef w(k, p, out):\n    f = p.f\n    f[k] = 1.0\n"
        "    p.g[k, 0] += 1.0\n    out[k] = p.h[k]\n    v(k, p)\n"
        "@kernel(inline=True)\ndef v(k, p):\n    p.v[k] = 0.0\n"
        "@kernel(inline=True)\ndef alone(k, p):\n    p.a[k] = 0.0\n"
        "@kernel\ndef called(p):\n    p.f[0] = 1.0\n    v(0, p)\n"
        "@kernel(parallel=True)\ndef loop(p, out):\n    q = p.q\n    q[0] = 1.0\n"
        "    for k in numba.prange(3):\n        w(k, p, out)\n        called(p)\n"
        "        p.f[k] = 2.0\n        out[k] = p.f[k]\n")
    # w and v are inlined into the parallel loop; ``alone`` and ``called`` are not, and
    # the write before the loop is outside it
    assert bundle_writes({"m": tmp_path / "m.py"}, root=tmp_path) == [
        "m.py:loop:25", "m.py:v:10", "m.py:w:4", "m.py:w:5"]


def test_no_parallel_loop_writes_through_a_bundle():
    found = bundle_writes(FILES)
    assert not found, ("writes into a bundle's array inside a prange loop or an inlined "
                       f"kernel, which numba drops in parallel loops: {found}")
