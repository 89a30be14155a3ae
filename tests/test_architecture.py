"""The layering of docs/architecture.md holds: every import in src/bondem (at module level
or inside a function) goes to a module of the same or a lower layer, every module has a
layer, and no modules import each other round a circle. The table is read from the doc,
so the doc and the code cannot drift apart."""
import ast
import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "bondem"


def layers():
    """{module name relative to bondem ("" for the package): layer} from the doc's table."""
    table = {}
    text = (ROOT / "docs" / "architecture.md").read_text()
    for number, cell in re.findall(r"^\| (\d+) \| (.*?) \|", text, re.M):
        for name in re.findall(r"`([\w.]+)`", cell):
            table["" if name == "bondem" else name] = int(number)
    return table


def modules():
    """{module name relative to bondem: path}."""
    out = {}
    for path in PACKAGE.rglob("*.py"):
        parts = list(path.relative_to(PACKAGE).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = path
    return out


def imports(name, path, known):
    """The bondem modules ``name`` imports (relative names), from every import statement."""
    package = name.split(".") if path.name == "__init__.py" else name.split(".")[:-1]
    package = [p for p in package if p]
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - (node.level - 1)]
            elif (node.module or "").split(".")[0] == "bondem":
                base = []
                node_module = node.module.split(".")[1:]
                targets = [".".join(node_module + [a.name]) for a in node.names]
                found.update(t if t in known else ".".join(node_module) for t in targets)
                continue
            else:
                continue
            module = base + (node.module.split(".") if node.module else [])
            for alias in node.names:
                full = ".".join(module + [alias.name])
                found.add(full if full in known else ".".join(module))
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.split(".")[0] == "bondem":
                    found.add(".".join(alias.name.split(".")[1:]))
    found.discard(name)
    return found


def layer_of(name, table):
    """The layer of a module: its own row, else its nearest package's."""
    parts = name.split(".") if name else []
    for k in range(len(parts), -1, -1):
        key = ".".join(parts[:k])
        if key in table and (k or name == ""):
            return table[key]
    return None


def test_every_module_has_a_layer():
    table = layers()
    assert len(table) > 20 and max(table.values()) == 10
    missing = sorted(m or "bondem" for m in modules() if layer_of(m, table) is None)
    assert not missing, f"modules without a row in docs/architecture.md: {missing}"


def test_no_import_points_up_the_layers():
    table = layers()
    known = modules()
    upward = []
    for name, path in known.items():
        for target in imports(name, path, known):
            if target in known and layer_of(target, table) > layer_of(name, table):
                upward.append(f"{name or 'bondem'} (layer {layer_of(name, table)}) imports "
                              f"{target or 'bondem'} (layer {layer_of(target, table)})")
    assert not upward, "\n".join(upward)


def test_no_import_circles():
    known = modules()
    graph = {name: {t for t in imports(name, path, known) if t in known}
             for name, path in known.items()}
    circles = []
    state = {}

    def visit(node, trail):
        state[node] = "open"
        for nxt in sorted(graph[node]):
            if state.get(nxt) == "open":
                circles.append(trail[trail.index(nxt):] + [nxt])
            elif nxt not in state:
                visit(nxt, trail + [nxt])
        state[node] = "done"

    for node in sorted(graph):
        if node not in state:
            visit(node, [node])
    assert not circles, "\n".join(" -> ".join(m or "bondem" for m in c) for c in circles)


@pytest.mark.parametrize("source, upward", [
    ("from ..lab.output import CAPTIONS\n", True),      # analysis reaching up to the lab
    ("from .. import Simulation\n", True),              # a module importing the API above it
    ("from .results import Results\n", False),
])
def test_the_check_sees_imports_inside_functions(tmp_path, source, upward):
    """The reader finds an import inside a function body, relative or absolute, as the
    old report's lab section and the LAMMPS export's Simulation were written."""
    table = layers()
    known = modules()
    path = tmp_path / "probe.py"
    path.write_text("def f():\n    " + source.replace("\n", "\n    ") + "\n")
    (target,) = imports("analysis.probe", path, known)
    assert (layer_of(target, table) > layer_of("analysis.probe", table)) == upward
