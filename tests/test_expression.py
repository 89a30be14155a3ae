"""The scene's formulas (expression.py): arithmetic of x, y, z and t evaluated with NumPy
against the same arithmetic written out, and everything that is not arithmetic refused
with a message naming it. Fast (no simulation): mutation testing runs it per mutant.
"""
import math

import numpy as np
import pytest

from bondem.expression import FUNCTIONS, Expression, flow_function


def test_formulas_evaluate_as_numpy_and_refuse_anything_else():
    x = np.array([0.1, -0.2, 0.3])
    e = Expression("2 * sin(pi * x) - x ** 2 / 3 + where(x > 0, exp(x), 0.5) % 1")
    expected = 2 * np.sin(np.pi * x) - x ** 2 / 3 + np.where(x > 0, np.exp(x), 0.5) % 1
    np.testing.assert_allclose(e(x=x), expected, rtol=1e-15)
    assert Expression("max(x, 0.25) + hypot(3, 4) - atan2(y, 1)")(x=x, y=0.5) \
        == pytest.approx(np.maximum(x, 0.25) + 5.0 - math.atan(0.5), rel=1e-15)
    assert Expression(2.5)() == 2.5 and Expression("-t")(t=3.0) == -3.0
    assert Expression("x * t").variables == {"x", "t"}
    for bad, word in [("__import__('os').system('ls')", "__import__"),
                      ("x.real", "not allowed"), ("x[0]", "not allowed"),
                      ("lambda: 1", "not allowed"), ("'a'", "not a number"),
                      ("sin(x, y)", "takes 1"), ("u + 1", "unknown name 'u'"),
                      ("sin(x=1)", "no keywords"), ("0 < x < 1", "not allowed"),
                      ("x +", "not an expression"), ("True", "not a number")]:
        with pytest.raises(ValueError, match=word.replace("(", r"\(")):
            Expression(bad)
    with pytest.raises(ValueError, match="no value"):
        Expression("x + y")(x=1.0)


@pytest.mark.parametrize("name", sorted(FUNCTIONS))
def test_every_function_is_numpys(name):
    """Each function against NumPy's or math's own at points inside its domain."""
    a = np.array([0.3, -0.45, 0.8])
    b = np.array([0.7, 0.2, -0.35])
    c = np.array([1.0, 0.0, 1.0])
    truth = {"sin": np.sin(a), "cos": np.cos(a), "tan": np.tan(a), "asin": np.arcsin(a),
             "acos": np.arccos(a), "atan": np.arctan(a), "atan2": np.arctan2(a, b),
             "sinh": np.sinh(a), "cosh": np.cosh(a), "tanh": np.tanh(a), "exp": np.exp(a),
             "log": np.log(np.abs(a)), "log10": np.log10(np.abs(a)),
             "sqrt": np.sqrt(np.abs(a)), "abs": np.abs(a), "sign": np.sign(a),
             "floor": np.floor(3 * a), "ceil": np.ceil(3 * a), "hypot": np.hypot(a, b),
             "min": np.minimum(a, b), "max": np.maximum(a, b), "where": np.where(c, a, b)}
    arguments = {"log": "abs(x)", "log10": "abs(x)", "sqrt": "abs(x)", "floor": "3 * x",
                 "ceil": "3 * x"}
    count = FUNCTIONS[name][1]
    text = f"{name}({', '.join([arguments.get(name, 'x'), 'y', 'z'][:count])})"
    if name == "where":
        text = "where(z, x, y)"
    np.testing.assert_array_equal(Expression(text)(x=a, y=b, z=c), truth[name])


def test_operators_comparisons_and_constants():
    x, t = np.array([0.25, -1.5, 2.0]), 0.75
    cases = {"x + t": x + t, "x - t": x - t, "x * t": x * t, "x / t": x / t,
             "x ** 2": x ** 2, "x % 0.4": np.mod(x, 0.4), "-x": -x, "+x": x,
             "x < 0.25": (x < 0.25) * 1.0, "x <= 0.25": (x <= 0.25) * 1.0,
             "x > 0.25": (x > 0.25) * 1.0, "x >= 0.25": (x >= 0.25) * 1.0,
             "pi * x": math.pi * x, "e ** x": math.e ** x, "3": np.full(3, 3.0)}
    for text, truth in cases.items():
        value = np.broadcast_to(Expression(text)(x=x, t=t), x.shape)
        np.testing.assert_allclose(value, truth, rtol=1e-15, atol=0, err_msg=text)
        assert value.dtype == np.float64
    # a comparison is 1 or 0 (not a boolean), so it can be scaled and summed
    assert Expression("(x > 0) * 2.5 + (x < 0)")(x=x).tolist() == [2.5, 1.0, 2.5]
    assert repr(Expression("x + 1")) == "Expression('x + 1')"
    with pytest.raises(ValueError, match="a string"):
        Expression(None)
    with pytest.raises(ValueError, match="a string"):
        Expression(True)


def test_messages_list_what_is_allowed_and_edge_inputs():
    with pytest.raises(ValueError) as error:
        Expression("u")
    assert "allowed: x, y, z, t, pi, e and the functions sin, cos, tan, asin" in str(
        error.value)
    with pytest.raises(ValueError) as error:
        Expression("open(x)")
    assert "allowed: sin, cos, tan, asin, acos, atan, atan2," in str(error.value)
    with pytest.raises(ValueError) as error:
        Expression("x[0]")
    assert ("(numbers, x y z t pi e, + - * / ** %, one comparison, and the listed "
            "functions only)") in str(error.value)
    # a division by zero is an inf for the caller to report, not a warning
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert Expression("1 / x")(x=np.array([0.0, 2.0])).tolist() == [np.inf, 0.5]
    # integers in, floats out; a comparison with the variable on its right
    value = Expression("x / 2")(x=np.array([1, 3]))
    assert value.dtype == np.float64 and value.tolist() == [0.5, 1.5]
    assert Expression("x")(x=np.array([1, 3])).dtype == np.float64
    assert Expression("0.5 < x")(x=np.array([0.25, 0.75])).tolist() == [0.0, 1.0]


def test_flow_function_gives_three_components_at_each_particle():
    u = flow_function(["2 * x + y", 0.5, "z * t"])
    position = np.array([[0.1, 0.2, 0.3], [-0.4, 0.5, -0.6]])
    np.testing.assert_allclose(u(position, 2.0), [[0.4, 0.5, 0.6], [-0.3, 0.5, -1.2]],
                               rtol=1e-15)
    assert u.formulas == ["2 * x + y", "0.5", "z * t"]
    assert u(position, 2.0).shape == (2, 3)
    # positions given as integers (a lattice in mm, say) are not truncated
    np.testing.assert_array_equal(flow_function(["x * t", "y / 4", "0"])([[1, 2, 3]], 0.5),
                                  [[0.5, 0.5, 0.0]])
    with pytest.raises(ValueError, match="3 components, got 2"):
        flow_function(["x", "y"])
