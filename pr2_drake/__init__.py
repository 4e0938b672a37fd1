"""pr2-drake: a Drake-native humanoid testbed re-creating the PR2 competition tasks.

The main entry points:

- :func:`pr2_drake.testbed.build_testbed` builds the testbed `Diagram` (plant, scene, sensors,
  referee) with the named ports of the PR2 action/observation contract.
- :class:`pr2_drake.env.Env` offers the same testbed as a plain step/reset environment with the
  original platform's observation and action dictionaries.
- The ``pr2-drake`` command line (:mod:`pr2_drake.cli`) runs, scores and benchmarks episodes.
"""

__version__ = "0.1.0"

from pr2_drake.learning.ids import register_when_gymnasium_loads as _register_gym_ids

_register_gym_ids()
