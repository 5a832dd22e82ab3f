#pragma once
// The Parameters glue of the Python bindings (python/parameters.cpp): Python values <-> the rows
// of the parameter table. What the other binding files need of it.

#include <pybind11/pybind11.h>

#include "cartesian_impedance/core/parameters.hpp"
#include "conversions.hpp"

namespace cartesian_impedance::python {

/// A Parameters object, a dict (dotted names or nested) or None (the defaults).
ci::Parameters read_parameters(py::handle object);

/// The partial update a dict (dotted names or nested) describes, decoded onto `base` (the
/// parameters in force): it names only the rows the dict gives. TypeError for anything but a
/// mapping and for a value of the wrong type, Error for the rest (the decoder's messages).
ci::ParameterUpdate read_parameter_update(py::handle mapping, const ci::Parameters& base);

}  // namespace cartesian_impedance::python
