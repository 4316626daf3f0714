"""The public face: every name in ``contopt.__all__`` resolves to the object its module defines, and
``import contopt`` stays light (no JAX until a name needs it)."""

import importlib
import subprocess
import sys

import contopt


def test_every_public_name_resolves_to_its_definition():
    for name in contopt.__all__:
        value = getattr(contopt, name)
        if name == "__version__":
            continue
        module = importlib.import_module(value.__module__)
        assert getattr(module, value.__name__) is value, name


def test_import_contopt_loads_no_jax():
    code = "import sys, contopt; print('jax' in sys.modules, 'numpy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.split()
    assert out == ["False", "False"]


def test_an_unknown_name_is_an_attribute_error():
    try:
        contopt.no_such_thing  # noqa: B018
    except AttributeError as err:
        assert "no_such_thing" in str(err)
    else:
        raise AssertionError("no AttributeError")
