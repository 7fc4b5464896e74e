"""senbench encoder plugin: ``mlp``, a state encoder that is a multilayer perceptron on
the flattened frame stack — the baseline a convolutional encoder should beat."""

from dataclasses import dataclass

import senbench


@dataclass
class MLPConfig:
    hidden: int = 256
    """Units of each of the two hidden layers."""
    layers: int = 2
    """Hidden layers."""

    def __post_init__(self):
        if self.hidden < 1 or self.layers < 1:
            raise ValueError("hidden and layers must be at least 1")


def build(input_shape: tuple[int, int, int], outputs: int, config: MLPConfig):
    """A torch module mapping float frames in [0, 1], (B, stack, H, W), to (B, outputs).
    senbench trains it (normalised targets, Adam on the squared error), caches it, and
    calls it on every frame of an ``encoded`` observation."""
    from torch import nn  # imported here: listing plugins does not pay for torch

    stack, height, width = input_shape
    modules: list[nn.Module] = [nn.Flatten()]
    width_in = stack * height * width
    for _ in range(config.layers):
        modules += [nn.Linear(width_in, config.hidden), nn.ReLU()]
        width_in = config.hidden
    modules.append(nn.Linear(width_in, outputs))
    return nn.Sequential(*modules)


MLP = senbench.EncoderSpec(
    name="mlp",
    build=build,
    config=MLPConfig,
    description="a multilayer perceptron on the flattened frames",
    # forward has no branch that depends on its input: senbench may freeze it into
    # TorchScript for inference (it keeps the frozen network only if it matches).
    traceable=True,
    batch_independent=True,
    search_space={"hidden": senbench.Choice((64, 128, 256, 512))},
)


@senbench.hookimpl
def register_encoders(register):
    register(MLP)
