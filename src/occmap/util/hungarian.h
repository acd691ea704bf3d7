// Optimal assignment (the Hungarian method, O(n^3) with potentials, rectangular allowed).
//
// cost is rows x cols, row-major. Returns for each row the column assigned to it, or -1. Pairs
// whose cost is >= forbidden_cost (e.g. beyond a gating distance) are never assigned, so a
// row may stay unassigned even when a column is free. The total cost of the assigned pairs is
// minimal among assignments of the same (maximal) number of allowed pairs.
//
//   std::vector<int> match = SolveAssignment(cost, rows, cols, /*forbidden_cost=*/0.5);
#pragma once

#include <limits>
#include <vector>

namespace occmap {

std::vector<int> SolveAssignment(const std::vector<double>& cost, int rows, int cols,
                                 double forbidden_cost = std::numeric_limits<double>::infinity());

}  // namespace occmap
