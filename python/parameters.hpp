#pragma once
// The Parameters glue of the Python bindings (python/parameters.cpp): Python values <-> the rows
// of the parameter table. What the other binding files need of it.

#include <pybind11/pybind11.h>

#include "cartesian_impedance/core/parameters.hpp"
#include "conversions.hpp"

namespace cartesian_impedance::python {

/// A Parameters object, a dict (dotted names or nested) or None (the defaults).
ci::Parameters read_parameters(py::handle object);

}  // namespace cartesian_impedance::python
