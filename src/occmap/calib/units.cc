#include "occmap/calib/units.h"

#include <fmt/core.h>

namespace occmap {

Result<double> MetresPerUnit(std::string_view unit) {
  if (unit == "m" || unit == "metre" || unit == "metres" || unit == "meter" || unit == "meters") return 1.0;
  if (unit == "cm" || unit == "centimetre" || unit == "centimetres" || unit == "centimeter" ||
      unit == "centimeters") {
    return 0.01;
  }
  if (unit == "mm" || unit == "millimetre" || unit == "millimetres" || unit == "millimeter" ||
      unit == "millimeters") {
    return 0.001;
  }
  return InvalidInput(fmt::format("unit: expected m, cm or mm, found '{}'", unit));
}

}  // namespace occmap
