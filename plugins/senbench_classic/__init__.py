"""Classic-control tasks of the SEN-DRL paper: MountainCar (discrete) and Pendulum (continuous).

The physics are gymnasium's; this plugin adds what senbench needs to know about each task:
its physical state, the bounds of that state, the return that counts as solved, and a fast
renderer of the state (``renderers.py``).
"""

import senbench
from senbench_classic.bars import with_bars
from senbench_classic.gym_ids import register_gymnasium_ids
from senbench_classic.mountaincar import MOUNTAINCAR
from senbench_classic.pendulum import PENDULUM

register_gymnasium_ids()  # senbench/PixelMountainCar-v0, senbench/PixelPendulum-v0


# The same tasks drawn as plain bars of their observation: the pixel learners' control.
MOUNTAINCAR_BARS = with_bars(MOUNTAINCAR, MOUNTAINCAR.state_low, MOUNTAINCAR.state_high)
PENDULUM_BARS = with_bars(PENDULUM, (-1.0, -1.0, -8.0), (1.0, 1.0, 8.0))


@senbench.hookimpl
def register_envs(register):
    register(MOUNTAINCAR)
    register(PENDULUM)
    register(MOUNTAINCAR_BARS)
    register(PENDULUM_BARS)
