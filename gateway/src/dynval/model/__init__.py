"""Lumped-mass chain models (report Section 4.1): the schema (schema.py), the element registry
(elements.py), the file formats (formats.py), validation with the core's limits
(validation.py), simulation through the C core's model and observer (simulation.py) and
residuals against recorded tests (residual.py). ``from dynval import model as mdl`` gives the
public names of all of them."""
from __future__ import annotations

from dynval.model.elements import (
                                   REGISTRY,
                                   SIDES,
                                   ConstantForce,
                                   Contact,
                                   CubicSpring,
                                   Element,
                                   Friction,
                                   StickSlip,
                                   VVDamper,
)
from dynval.model.formats import from_dict, load, save, to_dict
from dynval.model.residual import (
                                   ChannelResidual,
                                   ResidualResult,
                                   input_channel,
                                   residual,
                                   simulate_recording,
)
from dynval.model.schema import (
                                   DAMPING_TYPES,
                                   DAQ_CUTOFF,
                                   DAQ_FILTER_TYPES,
                                   FORMAT,
                                   INPUT_KINDS,
                                   INTERPOLATIONS,
                                   OUTPUT_KINDS,
                                   Damping,
                                   DaqFilter,
                                   Input,
                                   Link,
                                   Model,
                                   Output,
                                   param_unit,
)
from dynval.model.simulation import (
                                   Linear,
                                   PreparedInput,
                                   _Core,
                                   damping_matrix_explicit,
                                   free_response,
                                   interpolate_input,
                                   linear,
                                   modes,
                                   natural_frequencies,
                                   oversample_factor,
                                   predict_observed,
                                   prepare_input,
                                   simulate,
                                   simulate_batch,
                                   simulate_blocks,
                                   stiffness_matrix,
)
from dynval.model.validation import validate

ELEMENT_TYPES = tuple(REGISTRY)

__all__ = ["DAMPING_TYPES", "DAQ_CUTOFF", "DAQ_FILTER_TYPES", "ELEMENT_TYPES", "FORMAT",
           "INPUT_KINDS", "INTERPOLATIONS", "DaqFilter",
           "OUTPUT_KINDS", "REGISTRY", "SIDES", "ChannelResidual", "ConstantForce", "Contact",
           "CubicSpring", "Damping", "Element", "Friction", "Input", "Linear", "Link", "Model",
           "Output", "PreparedInput", "ResidualResult", "StickSlip", "VVDamper", "_Core",
           "damping_matrix_explicit", "free_response", "from_dict", "input_channel",
           "interpolate_input", "linear", "load", "modes", "natural_frequencies",
           "oversample_factor", "param_unit", "predict_observed", "prepare_input", "residual",
           "save", "simulate", "simulate_batch", "simulate_blocks", "simulate_recording",
           "stiffness_matrix",
           "to_dict", "validate"]
