"""Motion models (CV, CA, Singer; spec 004 polynomial, coordinated turn, m = 3 embedding,
Van Loan discretisation) and measurement models (radar polar, Cartesian)."""

from skytrack.models.discretize import input_response, singer_input, van_loan
from skytrack.models.embedding import EmbeddedAxis, embed
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
from skytrack.models.polynomial import PolynomialAxis, dwna, dwpa, polynomial
from skytrack.models.turn import CoordinatedTurn, coordinated_turn

__all__ = [
    "AxisModel",
    "CartesianPositionModel",
    "ConstantAccelerationAxis",
    "ConstantVelocityAxis",
    "CoordinatedTurn",
    "EmbeddedAxis",
    "MotionModel",
    "POLAR_COMPONENTS",
    "PolarMeasurementModel",
    "PolynomialAxis",
    "SingerAxisModel",
    "block_diag_batch",
    "constant_acceleration",
    "constant_velocity",
    "coordinated_turn",
    "dwna",
    "dwpa",
    "embed",
    "input_response",
    "polynomial",
    "singer",
    "singer_input",
    "state_indices",
    "van_loan",
]
