// Length units of calibration files, converted to metres once, when a file is read.
//
//   OCCMAP_ASSIGN_OR_RETURN(double m_per_unit, MetresPerUnit("cm"));   // 0.01
#pragma once

#include <string_view>

#include "occmap/util/status.h"

namespace occmap {

// "m", "cm" or "mm" (also "metre(s)", "centimetre(s)", "millimetre(s)").
Result<double> MetresPerUnit(std::string_view unit);

}  // namespace occmap
