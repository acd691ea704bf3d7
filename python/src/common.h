// What the binding files share: Status to Python exceptions, NumPy views of occmap's buffers.
#pragma once

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <exception>
#include <string>
#include <utility>

#include "occmap/util/image.h"
#include "occmap/util/status.h"

namespace occmap::python {

namespace py = pybind11;

// A failed Status on its way to Python: the translator (module.cc) raises the exception type of
// its code with its message unchanged.
class StatusError : public std::exception {
 public:
  explicit StatusError(Status status) : status_(std::move(status)) {}
  const char* what() const noexcept override { return status_.message().c_str(); }
  const Status& status() const { return status_; }

 private:
  Status status_;
};

inline void ThrowIfError(const Status& status) {
  if (!status.ok()) throw StatusError(status);
}
template <typename T>
T Unwrap(Result<T>&& result) {
  if (!result.ok()) throw StatusError(result.status());
  return std::move(result).value();
}
[[noreturn]] inline void ThrowInvalid(std::string message) { throw StatusError(InvalidInput(std::move(message))); }

// A C-contiguous uint8 array, converted (bool, other integer types) or copied when it is not one.
using U8Array = py::array_t<uint8_t, py::array::c_style | py::array::forcecast>;

// A view of a 2-D uint8 array (rows, columns); `what` names the argument in the message.
ImageView<const uint8_t> GrayView(const U8Array& array, const std::string& what);

// A copy of an image as a (rows, columns) or (rows, columns, 3) array.
py::array_t<uint8_t> ToArray(ImageView<const uint8_t> image);
py::array_t<uint8_t> ToArray(ImageView<const Rgb8> image);

void BindCore(py::module_& m);
void BindSim(py::module_& m);

}  // namespace occmap::python
