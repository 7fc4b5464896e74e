"""Built-in samplers of labelled (frame stack, observation) data for state encoders.

The paper's d% is not a sampler of its own: every encoder spec takes a ``fraction`` of the
pool its sampler draws, so d composes with any sampler."""

import senbench
from senbench_samplers.rollout import ROLLOUT
from senbench_samplers.uniform import UNIFORM


@senbench.hookimpl
def register_samplers(register):
    register(UNIFORM)
    register(ROLLOUT)
