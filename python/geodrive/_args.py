"""Argument errors of geodrive's functions: one line naming the argument.

pybind11 answers an argument it cannot convert with a TypeError listing the
whole signature and the repr of every argument (arrays included). ``checked``
wraps a geodrive._core function or method: a call that pybind11 refuses is
bound to the function's parameters (read from the signature pybind11 writes
first in ``__doc__``) and each argument is checked against its pybind11 type,
and the first one that does not fit raises

- ``TypeError("render(): argument 'size' must be a pair of ints, not str")``
  for a wrong type, a missing, unknown or repeated argument;
- ``ValueError`` for a value of the right type that cannot be used: a path or
  text that is not valid UTF-8 (undecodable bytes) or holds a NUL byte, an
  int out of range.

Calls that convert cost one try block more. Paths (``os.PathLike`` in the
signature: the PathArg parameters of python/bindings.cc) take str, bytes and
os.PathLike (pathlib.Path).
"""
import functools
import numbers
import operator
import os

import numpy as _np

_INCOMPATIBLE = "incompatible function arguments"
_C_INT = (-(2 ** 31), 2 ** 31)  # pybind11's int parameters are C int or size_t


def _split_top(text, sep=","):
    """Splits `text` at `sep` outside brackets and quotes."""
    parts, depth, quote, start = [], 0, None, 0
    for i, ch in enumerate(text):
        if quote:
            if ch == quote:
                quote = None
        elif ch in "'\"":
            quote = ch
        elif ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        elif ch == sep and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    parts.append(text[start:])
    return [p.strip() for p in parts if p.strip()]


def _parameters(fn):
    """[(name, pybind11 type, has_default)] from fn's pybind11 signature."""
    first = (fn.__doc__ or "").split("\n", 1)[0]
    open_ = first.find("(")
    depth, close = 0, -1
    for i in range(open_, len(first)):
        depth += first[i] in "([{"
        depth -= first[i] in ")]}"
        if depth == 0:
            close = i
            break
    params = []
    for part in _split_top(first[open_ + 1:close]):
        name, _, rest = part.partition(":")
        type_, eq, _ = rest.partition(" = ")
        params.append((name.strip(), type_.strip(), bool(eq)))
    return params


def _type_name(value):
    return type(value).__name__


def _is_int(value):
    if isinstance(value, (float, _np.floating, str, bytes)):
        return False
    try:
        operator.index(value)
        return True
    except TypeError:
        return False


def _is_float(value):
    if isinstance(value, (str, bytes)):
        return False
    return isinstance(value, numbers.Real) or hasattr(type(value), "__float__") \
        or hasattr(type(value), "__index__")


def _is_sequence(value):
    return not isinstance(value, (str, bytes, dict)) and \
        hasattr(value, "__len__") and hasattr(value, "__getitem__")


def _utf8_problem(text):
    """Why str or bytes `text` cannot be passed as UTF-8 text, or None."""
    try:
        data = text if isinstance(text, bytes) else text.encode("utf-8")
        if isinstance(text, bytes):
            text.decode("utf-8")
    except UnicodeError:
        return "is not valid UTF-8: %s" % ascii(text)[:120]
    if b"\0" in data:
        return "contains a NUL byte: %s" % ascii(text)[:120]
    return None


class _Problem(Exception):
    """What is wrong with one argument: (exception type, message tail)."""

    def __init__(self, kind, tail):
        super().__init__(tail)
        self.kind, self.tail = kind, tail


def _must(expected, value):
    return _Problem(TypeError, "must be %s, not %s" % (expected, _type_name(value)))


def _check(type_, value, core):
    """Raises _Problem when `value` does not convert to pybind11 `type_`."""
    if type_.startswith("Optional[") and type_.endswith("]"):
        if value is not None:
            try:
                _check(type_[len("Optional["):-1], value, core)
            except _Problem as p:
                if p.kind is TypeError:
                    p.tail = p.tail.replace("must be ", "must be None or ", 1)
                raise
        return
    if type_ == "object":
        return
    if type_ == "os.PathLike":
        if not isinstance(value, (str, bytes)) and \
                not hasattr(type(value), "__fspath__"):
            raise _must("str or os.PathLike", value)
        path = os.fspath(value)
        problem = _utf8_problem(path)
        if problem:
            raise _Problem(ValueError, problem)
        return
    if type_ == "str":
        if not isinstance(value, (str, bytes)):
            raise _must("str", value)
        problem = _utf8_problem(value)
        if problem:
            raise _Problem(ValueError, problem)
        return
    if type_ == "int":
        if not _is_int(value):
            raise _must("int", value)
        v = operator.index(value)
        if not _C_INT[0] <= v < _C_INT[1]:
            raise _Problem(ValueError, "is out of range: %d" % v)
        return
    if type_ == "float":
        if not _is_float(value):
            raise _must("float", value)
        return
    if type_ == "bool":
        if value is not None and not isinstance(value, (numbers.Number, _np.bool_)):
            raise _must("bool", value)
        return
    if type_ == "dict":
        if not isinstance(value, dict):
            raise _must("dict", value)
        return
    if type_.startswith("numpy.ndarray[") and type_.endswith("]"):
        dtype = type_[len("numpy.ndarray["):-1].replace("numpy.", "")
        try:
            _np.asarray(value, dtype=dtype)
        except (TypeError, ValueError, OverflowError):
            raise _must("a %s array (or array-like)" % dtype, value) from None
        return
    if type_ == "numpy.ndarray":  # dtype checked by the function itself
        if not isinstance(value, _np.ndarray) and \
                _np.asarray(value).dtype == object:
            raise _must("a numpy array", value)
        return
    if type_.startswith(("Tuple[", "List[")) and type_.endswith("]"):
        items = _split_top(type_[type_.index("[") + 1:-1])
        if type_.startswith("Tuple["):
            expected = "a tuple (%s)" % ", ".join(items)
        else:
            expected = "a list of %s" % items[0]
        if not _is_sequence(value) or \
                (type_.startswith("Tuple[") and len(value) != len(items)):
            raise _must(expected, value)
        for i, item in enumerate(value):
            try:
                _check(items[i] if type_.startswith("Tuple[") else items[0],
                       item, core)
            except _Problem as p:
                p.tail = "item %d %s" % (i, p.tail)
                raise
        return
    if type_.startswith("geodrive._core."):
        cls = getattr(core, type_[len("geodrive._core."):], None)
        if cls is not None and value is not None and not isinstance(value, cls):
            raise _must(cls.__name__, value)
    # Other types: not checked here (the fallback message applies).


def _explain(name, fn, args, kwargs, core):
    """The exception for a call pybind11 refused (one line)."""
    params = _parameters(fn)
    names = [p[0] for p in params]
    if params and params[0][0] == "self":
        label = "%s.%s()" % (params[0][1].rsplit(".", 1)[-1], name)
    else:
        label = "%s()" % name
    if len(args) > len(params):
        return TypeError("%s takes at most %d arguments (%d given)" % (
            label, len(params), len(args)))
    bound = dict(zip(names, args))
    for key, value in kwargs.items():
        if key not in names:
            return TypeError("%s got an unexpected keyword argument '%s'" % (label, key))
        if key in bound:
            return TypeError("%s got multiple values for argument '%s'" % (label, key))
        bound[key] = value
    for pname, _, has_default in params:
        if pname not in bound and not has_default:
            return TypeError("%s missing required argument '%s'" % (label, pname))
    for pname, type_, _ in params:
        if pname not in bound or pname == "self":
            continue
        try:
            _check(type_, bound[pname], core)
        except _Problem as p:
            return p.kind("%s argument '%s' %s" % (label, pname, p.tail))
    return TypeError("%s: the arguments do not fit %s" % (
        label, (fn.__doc__ or "").split("\n", 1)[0]))


def check(label, name, type_, value, core=None):
    """Raises the one-line error when `value` does not fit pybind11 type
    `type_` (for Python functions: label "PairDataset()", name "manifest")."""
    try:
        _check(type_, value, core)
    except _Problem as p:
        raise p.kind("%s argument '%s' %s" % (label, name, p.tail)) from None


def checked(fn, core, name=None):
    """fn (a geodrive._core function) with one-line argument errors."""
    public = name or fn.__name__

    @functools.wraps(fn)
    def call(*args, **kwargs):
        try:
            return fn(*args, **kwargs)
        except TypeError as e:
            if _INCOMPATIBLE not in str(e).split("\n", 1)[0]:
                raise
            error = _explain(public, fn, args, kwargs, core)
        raise error from None

    call.__name__ = call.__qualname__ = public
    call.__module__ = "geodrive"
    return call


def check_methods(cls, core):
    """Wraps the methods of a geodrive._core class with `checked`."""
    for attr, value in list(vars(cls).items()):
        fn = getattr(value, "__func__", None)
        if attr.startswith("__") or fn is None or not callable(fn):
            continue
        wrapped = checked(fn, core, attr)
        wrapped.__qualname__ = "%s.%s" % (cls.__name__, attr)
        setattr(cls, attr, wrapped)
