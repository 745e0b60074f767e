"""The plugin's tests, beside it: slipbench's conformance suite, one pytest item per check
(``pytest plugins/``). Files named test_*.py or conftest.py in a plugin folder are not plugins."""

from energy import Energy

from slipbench.testing import parametrize_with_checks


@parametrize_with_checks([Energy()])
def test_conformance(plugin, check):
    check(plugin)
