#pragma once
// The message of the library's Error that a call throws, for tests that compare it whole.

#include <functional>
#include <string>

#include "cartesian_impedance/core/error.hpp"

namespace test_errors {

/// What `call` throws as cartesian_impedance::Error, or "<no error>" if it returns.
inline std::string error_of(const std::function<void()>& call) {
  try {
    call();
  } catch (const cartesian_impedance::Error& error) {
    return error.what();
  }
  return "<no error>";
}

}  // namespace test_errors
