// The extension module occmap._occmap: exceptions, then the bindings of core.cc and sim.cc.
#include <Python.h>

#include <cstring>

#include "common.h"
#include "occmap/fusion/occupancy_map.h"

namespace occmap::python {

ImageView<const uint8_t> GrayView(const U8Array& array, const std::string& what) {
  if (array.ndim() != 2) {
    ThrowInvalid(what + ": expected a 2-D array (rows, columns), found " + std::to_string(array.ndim()) + "-D");
  }
  if (array.shape(0) == 0 || array.shape(1) == 0 || array.shape(0) > (1 << 20) || array.shape(1) > (1 << 20)) {
    ThrowInvalid(what + ": expected 1 to 1048576 rows and columns, found " + std::to_string(array.shape(0)) + " x " +
                 std::to_string(array.shape(1)));
  }
  return {array.data(), static_cast<int>(array.shape(1)), static_cast<int>(array.shape(0)), array.shape(1)};
}

py::array_t<uint8_t> ToArray(ImageView<const uint8_t> image) {
  py::array_t<uint8_t> out({image.height(), image.width()});
  auto w = out.mutable_unchecked<2>();
  for (int y = 0; y < image.height(); ++y) std::memcpy(w.mutable_data(y, 0), image.row(y), static_cast<size_t>(image.width()));
  return out;
}

py::array_t<uint8_t> ToArray(ImageView<const Rgb8> image) {
  py::array_t<uint8_t> out({image.height(), image.width(), 3});
  auto w = out.mutable_unchecked<3>();
  for (int y = 0; y < image.height(); ++y) std::memcpy(w.mutable_data(y, 0, 0), image.row(y), 3 * static_cast<size_t>(image.width()));
  return out;
}

namespace {

// The exception types, one per StatusCode; each also derives from the builtin a Python user
// would catch for it (ValueError for bad input, FileNotFoundError, OSError).
PyObject* exception_for[7] = {};

PyObject* NewException(py::module_& m, const char* name, const char* doc, py::tuple bases) {
  const std::string full = std::string("occmap.") + name;
  PyObject* type = PyErr_NewExceptionWithDoc(full.c_str(), doc, bases.ptr(), nullptr);
  if (type == nullptr) throw py::error_already_set();
  m.add_object(name, py::handle(type));
  return type;  // one reference kept for the module's life
}

}  // namespace

PYBIND11_MODULE(_occmap, m) {
  m.doc() = "occmap's C++ core: sites, lookup tables, fusion, objects, trackers, simulator, metrics.";
  m.attr("__version__") = OCCMAP_VERSION;

  py::object error = py::reinterpret_borrow<py::object>(
      NewException(m, "Error", "Base class of occmap's errors; the message is occmap's own (file, line, field).",
                   py::make_tuple(py::reinterpret_borrow<py::object>(PyExc_Exception))));
  auto with = [&](PyObject* builtin) {
    return py::make_tuple(error, py::reinterpret_borrow<py::object>(builtin));
  };
  exception_for[static_cast<int>(StatusCode::kInvalidInput)] =
      NewException(m, "InvalidInputError", "Malformed input: a site, option, array or file content (a ValueError).",
                   with(PyExc_ValueError));
  exception_for[static_cast<int>(StatusCode::kNotFound)] =
      NewException(m, "NotFoundError", "A named input does not exist (a FileNotFoundError).", with(PyExc_FileNotFoundError));
  exception_for[static_cast<int>(StatusCode::kDataLoss)] =
      NewException(m, "DataLossError", "A file is truncated or corrupt (a ValueError).", with(PyExc_ValueError));
  exception_for[static_cast<int>(StatusCode::kResourceExhausted)] = NewException(
      m, "ResourceExhaustedError", "The input asks for more memory than allowed (a ValueError).", with(PyExc_ValueError));
  exception_for[static_cast<int>(StatusCode::kIoError)] =
      NewException(m, "IoError", "An output could not be written (an OSError).", with(PyExc_OSError));
  exception_for[static_cast<int>(StatusCode::kInternal)] =
      NewException(m, "InternalError", "occmap's own failure, not one of the input (a RuntimeError).", with(PyExc_RuntimeError));

  py::register_exception_translator([](std::exception_ptr p) {
    try {
      if (p) std::rethrow_exception(p);
    } catch (const StatusError& e) {
      const int code = static_cast<int>(e.status().code());
      PyObject* type = code > 0 && code < 7 ? exception_for[code] : exception_for[static_cast<int>(StatusCode::kInternal)];
      PyErr_SetString(type, e.status().message().c_str());
    }
  });

  m.attr("UNSEEN") = static_cast<int>(CellState::kUnseen);
  m.attr("FREE") = static_cast<int>(CellState::kFree);
  m.attr("OCCUPIED") = static_cast<int>(CellState::kOccupied);
  BindCore(m);
  BindSim(m);
}

}  // namespace occmap::python
