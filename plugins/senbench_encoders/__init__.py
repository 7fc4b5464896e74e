"""Built-in state encoder architectures: the SEN-DRL paper's residual network, the
Nature-DQN CNN, and a spatial-softmax keypoint network built to read positions, so that
architecture is a real axis of a suite."""

import senbench
from senbench_encoders.keypoints import KEYPOINTS
from senbench_encoders.nature_cnn import NATURE_CNN
from senbench_encoders.sen_resnet import SEN_RESNET


@senbench.hookimpl
def register_encoders(register):
    register(SEN_RESNET)
    register(NATURE_CNN)
    register(KEYPOINTS)
