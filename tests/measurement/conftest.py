"""The simulated sets more than one test module scores: built once per session."""

import pytest

from measurement.cases import layer_cases, standard_cases


@pytest.fixture(scope="session")
def standard_set():
    # 16x16; Hertz, cone, flat punch, uniform ellipse; shear ratio 0, 0.2, 0.4 in
    # golden-angle directions; h/pitch 0.5, 1, 1.5; 1% noise; seed fixed in standard_cases.
    # Half-space data: this is the set the half-space kernels and the functional were tuned on.
    return standard_cases(medium="halfspace")


@pytest.fixture(scope="session")
def layer_noisy():
    # the physics set (layer_cases): its own seed and h/p 2, nothing was tuned on it
    return layer_cases(noise=0.01)
