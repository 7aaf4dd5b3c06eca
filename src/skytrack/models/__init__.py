"""Motion models (CV, CA, Singer) and measurement models (radar polar, Cartesian)."""

from skytrack.models.measurement import (
    CartesianPositionModel,
    POLAR_COMPONENTS,
    PolarMeasurementModel,
    state_indices,
)
from skytrack.models.motion import (
    AxisModel,
    ConstantAccelerationAxis,
    ConstantVelocityAxis,
    MotionModel,
    SingerAxisModel,
    block_diag_batch,
    constant_acceleration,
    constant_velocity,
    singer,
)

__all__ = [
    "AxisModel",
    "CartesianPositionModel",
    "ConstantAccelerationAxis",
    "ConstantVelocityAxis",
    "MotionModel",
    "POLAR_COMPONENTS",
    "PolarMeasurementModel",
    "SingerAxisModel",
    "block_diag_batch",
    "constant_acceleration",
    "constant_velocity",
    "singer",
    "state_indices",
]
