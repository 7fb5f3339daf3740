"""The one table of the models a scene can switch on (scene section ``models:``).

Each row is a model module's :class:`~lander_sim.physics.models.base.ModelEntry`: the module owns
its config dataclass, the parsing of its section (with the scene loader's error style) and its
construction. The scene loader parses ``models:`` through this table
(:func:`lander_sim.scenes.loader.parse_scene`) and the simulation builds the models through it
(:func:`lander_sim.simulation.build_dynamics`), in the table's order, which is also the order in
which forces are summed (so it is part of a flight's bit-for-bit identity).

Adding a force model is one module (a force class with ``name``/``add``, a config, ``parse``,
``build`` and ``ENTRY``) and one row here: see docs/physics.md, "Adding a model", and
``test/physics/test_model_table.py``.
"""
from __future__ import annotations

from lander_sim.physics.models import atmosphere, constant_force, drag, gravity, ground, parachute, thrusters
from lander_sim.physics.models.base import ModelEntry

#: key -> entry, in build (and force-summing) order.
MODELS: dict[str, ModelEntry] = {
    e.key: e
    for e in (
        gravity.ENTRY,
        atmosphere.ENTRY,
        drag.ENTRY,
        parachute.ENTRY,
        thrusters.ENTRY,
        constant_force.ENTRY,
        ground.ENTRY,
    )
}
