"""multiform: teach a robot a dynamic skill by definition, demonstration and evaluation.

The three forms of teaching live in three sub-packages:

* :mod:`multiform.petri` — the adaptive Petri net (definition),
* :mod:`multiform.learn` — GP control laws, SVM judges, learned conditions (demonstration, evaluation),
* :mod:`multiform.adapt` — diagnosis and repair of the net from practice (the adaptive part).
"""

__version__ = "0.1.0"

from .envs import rendering as _rendering  # noqa: E402,F401  (MuJoCo's offscreen GL, chosen before mujoco loads)
