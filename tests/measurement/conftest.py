"""The simulated sets more than one test module scores: built once per session."""

import pytest

from measurement.cases import layer_cases, standard_cases, validation_cases


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


@pytest.fixture(scope="session")
def validation_set():
    """``validation_set(noise)``: measurement.cases.validation_cases(noise=noise), built once per noise.

    Cases are frozen and their frames read-only: tests that share one only read it.
    """
    made = {}

    def get(noise=0.01):
        if noise not in made:
            made[noise] = validation_cases(noise=noise)
        return made[noise]
    return get
