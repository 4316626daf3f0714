"""The built-in responses as problem files name them (contopt.responses.catalog) are the classes'
own: the same names, each class taking exactly the options listed, in its constructor's order."""

import inspect

from contopt.responses import BUILTIN
from contopt.responses.catalog import OPTIONS, RESPONSES


def test_every_builtin_response_takes_the_options_the_catalog_lists():
    assert sorted(RESPONSES) == sorted(BUILTIN)
    for name, cls in BUILTIN.items():
        parameters = inspect.signature(cls).parameters
        taken = tuple(p for p in parameters if p != "name")
        assert taken == RESPONSES[name].options, name
        needed = tuple(p for p in taken if parameters[p].default is inspect.Parameter.empty)
        assert needed == RESPONSES[name].required, name
    used = {"name"} | {option for kind in RESPONSES.values() for option in kind.options}
    assert used == set(OPTIONS)
