"""Formulas in scene files: a small, safe expression language evaluated with NumPy.

A formula is one Python expression of the variables x, y, z (m) and t (s), numbers, the
constants pi and e, the operators + - * / ** % and the comparisons < <= > >= (true: 1),
and the functions below (element-wise); ``where(c, a, b)`` picks a where c holds, else b.
Nothing else parses: no attributes, subscripts, keywords, strings or other names, so a
scene can run nothing but arithmetic. ``Expression(text)(x=..., t=...)`` evaluates it
over arrays (broadcast); ``flow_function`` turns three of them into a fluid velocity.
"""
import ast
import math
import operator

import numpy as np

VARIABLES = ("x", "y", "z", "t")
CONSTANTS = {"pi": math.pi, "e": math.e}
FUNCTIONS = {
    "sin": (np.sin, 1), "cos": (np.cos, 1), "tan": (np.tan, 1), "asin": (np.arcsin, 1),
    "acos": (np.arccos, 1), "atan": (np.arctan, 1), "atan2": (np.arctan2, 2),
    "sinh": (np.sinh, 1), "cosh": (np.cosh, 1), "tanh": (np.tanh, 1), "exp": (np.exp, 1),
    "log": (np.log, 1), "log10": (np.log10, 1), "sqrt": (np.sqrt, 1), "abs": (np.abs, 1),
    "sign": (np.sign, 1), "floor": (np.floor, 1), "ceil": (np.ceil, 1),
    "hypot": (np.hypot, 2), "min": (np.minimum, 2), "max": (np.maximum, 2),
    "where": (np.where, 3),
}
BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
          ast.Div: operator.truediv, ast.Pow: operator.pow, ast.Mod: np.mod}
UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos}
COMPARE = {ast.Lt: np.less, ast.LtE: np.less_equal, ast.Gt: np.greater,
           ast.GtE: np.greater_equal}


class Expression:
    """A formula of x, y, z (m) and t (s) (module docstring). ValueError names what is
    not allowed; ``variables``: the ones it uses."""

    def __init__(self, text):
        if isinstance(text, (int, float)) and not isinstance(text, bool):
            text = repr(float(text))
        if not isinstance(text, str):
            raise ValueError(f"expected a formula (a string) or a number, got {text!r}")
        self.text = text
        try:
            tree = ast.parse(text.strip(), mode="eval")
        except SyntaxError as error:
            raise ValueError(f"formula {text!r}: not an expression ({error.msg})") from None
        self.variables = set()
        self._check(tree.body)
        self._tree = tree.body

    def _check(self, node):
        if isinstance(node, ast.Constant):
            if not isinstance(node.value, (int, float)) or isinstance(node.value, bool):
                raise ValueError(f"formula {self.text!r}: {node.value!r} is not a number")
        elif isinstance(node, ast.Name):
            if node.id in VARIABLES:
                self.variables.add(node.id)
            elif node.id not in CONSTANTS:
                raise ValueError(f"formula {self.text!r}: unknown name {node.id!r}; allowed: "
                                 f"{', '.join(VARIABLES + tuple(CONSTANTS))} and the functions "
                                 f"{', '.join(FUNCTIONS)}")
        elif isinstance(node, ast.BinOp) and type(node.op) in BINARY:
            self._check(node.left)
            self._check(node.right)
        elif isinstance(node, ast.UnaryOp) and type(node.op) in UNARY:
            self._check(node.operand)
        elif isinstance(node, ast.Compare) and len(node.ops) == 1 \
                and type(node.ops[0]) in COMPARE:
            self._check(node.left)
            self._check(node.comparators[0])
        elif isinstance(node, ast.Call):
            name = node.func.id if isinstance(node.func, ast.Name) else None
            if name not in FUNCTIONS:
                raise ValueError(f"formula {self.text!r}: unknown function "
                                 f"{ast.unparse(node.func)!r}; allowed: {', '.join(FUNCTIONS)}")
            if node.keywords or len(node.args) != FUNCTIONS[name][1]:
                raise ValueError(f"formula {self.text!r}: {name} takes "
                                 f"{FUNCTIONS[name][1]} argument(s), no keywords")
            for argument in node.args:
                self._check(argument)
        else:
            raise ValueError(f"formula {self.text!r}: {ast.unparse(node)!r} is not allowed "
                             "(numbers, x y z t pi e, + - * / ** %, one comparison, and "
                             "the listed functions only)")

    def __call__(self, **values):
        """The formula's value, the variables given as numbers or arrays (broadcast)."""
        missing = self.variables - set(values)
        if missing:
            raise ValueError(f"formula {self.text!r}: no value for {sorted(missing)}")
        with np.errstate(all="ignore"):   # a non-finite result is the caller's to report
            return np.asarray(self._evaluate(self._tree, values), dtype=np.float64)

    def _evaluate(self, node, values):
        if isinstance(node, ast.Constant):
            return float(node.value)
        if isinstance(node, ast.Name):
            return values[node.id] if node.id in VARIABLES else CONSTANTS[node.id]
        if isinstance(node, ast.BinOp):
            return BINARY[type(node.op)](self._evaluate(node.left, values),
                                         self._evaluate(node.right, values))
        if isinstance(node, ast.UnaryOp):
            return UNARY[type(node.op)](self._evaluate(node.operand, values))
        if isinstance(node, ast.Compare):
            return COMPARE[type(node.ops[0])](self._evaluate(node.left, values),
                                              self._evaluate(node.comparators[0], values)
                                              ).astype(np.float64)
        function = FUNCTIONS[node.func.id][0]
        return function(*(self._evaluate(a, values) for a in node.args))

    def __repr__(self):
        return f"Expression({self.text!r})"


def flow_function(components):
    """A fluid velocity u(position (N,3) m, time s) -> (N,3) m/s from three formulas (or
    numbers) of x, y, z and t, its x, y and z components."""
    expressions = [Expression(c) for c in components]
    if len(expressions) != 3:
        raise ValueError(f"expected 3 components, got {len(expressions)}")

    def velocity(position, time):
        position = np.asarray(position, dtype=np.float64)
        values = {"x": position[:, 0], "y": position[:, 1], "z": position[:, 2],
                  "t": float(time)}
        out = np.empty_like(position)
        for k, expression in enumerate(expressions):
            out[:, k] = expression(**values)
        return out

    velocity.formulas = [e.text for e in expressions]
    return velocity
