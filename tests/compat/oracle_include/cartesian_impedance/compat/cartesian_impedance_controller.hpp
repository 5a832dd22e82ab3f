#pragma once
// Stands in for the compatibility header when published_api_program.cpp is built against the
// oracle of the published semantics instead (see tests/CMakeLists.txt).

#include "support/published_reference.hpp"

namespace cartesian_impedance_controller {
using CartesianImpedanceController = published_reference::Controller;
}  // namespace cartesian_impedance_controller
