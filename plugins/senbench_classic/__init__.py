"""Classic-control tasks of the SEN-DRL paper: MountainCar (discrete) and Pendulum (continuous).

The physics are gymnasium's; this plugin adds what senbench needs to know about each task:
its physical state, the bounds of that state, and the return that counts as solved.
"""

import senbench
from senbench_classic.mountaincar import MOUNTAINCAR
from senbench_classic.pendulum import PENDULUM


@senbench.hookimpl
def register_envs(register):
    register(MOUNTAINCAR)
    register(PENDULUM)
