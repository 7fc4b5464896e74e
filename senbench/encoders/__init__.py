"""State encoders: a request names one (request), a trained network reads frames (model),
training draws labelled frames and fits it (training), the cache trains each once (cache)."""

from senbench.encoders.cache import cache_dir, complete, load, load_or_train
from senbench.encoders.model import StateEncoder, build_model, observation_bounds  # noqa: I001
from senbench.encoders.request import TRAINING_THREADS, EncoderRequest, Training
from senbench.encoders.training import trace, train

__all__ = [
    "TRAINING_THREADS", "EncoderRequest", "StateEncoder", "Training", "build_model", "cache_dir",
    "complete", "load", "load_or_train", "observation_bounds", "trace",
    "train",
]
