#include "occmap/calib/tsai_yaml.h"

#include <fmt/core.h>

#include <cmath>

#include "occmap/geometry/rotation.h"
#include "occmap/util/file_util.h"
#include "occmap/util/yaml_util.h"

namespace occmap {
namespace fs = std::filesystem;

Result<TsaiParameters> ReadTsaiYaml(const fs::path& path, const std::string& camera, double metres_per_unit) {
  OCCMAP_ASSIGN_OR_RETURN(YamlField root, LoadYamlFile(path));
  if (!root.IsMap()) return root.Error("expected a map of Tsai parameters");
  YamlField block = root;
  if (!camera.empty()) {
    auto found = root.Find(camera);
    if (!found) {
      std::string names;
      for (const auto& kv : root.node()) {
        if (kv.first.IsScalar() && kv.second.IsMap()) names += (names.empty() ? "" : ", ") + kv.first.Scalar();
      }
      return root.Error(fmt::format("no camera '{}' (found: {})", camera, names.empty() ? "none" : names));
    }
    block = *found;
  } else if (!root.Has("f")) {
    return root.Error("expected Tsai parameters at the top level (or name a camera block)");
  }
  OCCMAP_RETURN_IF_ERROR(block.CheckKeys({"image_width", "image_height", "Ncx", "Nfx", "dx", "dy", "dpx", "dpy",
                                          "Cx", "Cy", "sx", "f", "kappa1", "Tx", "Ty", "Tz", "Rx", "Ry", "Rz",
                                          "r1", "r2", "r3", "r4", "r5", "r6", "r7", "r8", "r9",
                                          "camera_centre_world"}));
  TsaiParameters p;
  OCCMAP_ASSIGN_OR_RETURN(int64_t w, block.GetInt("image_width"));
  OCCMAP_ASSIGN_OR_RETURN(int64_t h, block.GetInt("image_height"));
  if (w <= 0 || h <= 0 || w > 65535 || h > 65535) {
    return block.Error(fmt::format("image size: expected 1..65535, found {}x{}", w, h));
  }
  p.image_size = {static_cast<int>(w), static_cast<int>(h)};
  struct Field {
    const char* key;
    double* dest;
  };
  double tx = 0, ty = 0, tz = 0, rx = 0, ry = 0, rz = 0;
  for (const Field& f : {Field{"Ncx", &p.Ncx}, Field{"Nfx", &p.Nfx}, Field{"dx", &p.dx_mm}, Field{"dy", &p.dy_mm},
                         Field{"Cx", &p.Cx_px}, Field{"Cy", &p.Cy_px}, Field{"sx", &p.sx}, Field{"f", &p.f_mm},
                         Field{"kappa1", &p.kappa1_per_mm2}, Field{"Tx", &tx}, Field{"Ty", &ty}, Field{"Tz", &tz},
                         Field{"Rx", &rx}, Field{"Ry", &ry}, Field{"Rz", &rz}}) {
    OCCMAP_ASSIGN_OR_RETURN(*f.dest, block.GetDouble(f.key));
  }
  for (const Field& f : {Field{"f", &p.f_mm}, Field{"dx", &p.dx_mm}, Field{"dy", &p.dy_mm},
                         Field{"Ncx", &p.Ncx}, Field{"Nfx", &p.Nfx}, Field{"sx", &p.sx}}) {
    if (!(*f.dest > 0)) {
      return block.Find(f.key)->Error(fmt::format("expected a positive value, found {}", *f.dest));
    }
  }
  p.cam_from_world_rotation = TsaiRotation(rx, ry, rz);
  p.cam_from_world_translation_m = Eigen::Vector3d(tx, ty, tz) * metres_per_unit;

  // Derived values that the file may carry: they must agree with the parameters.
  if (auto dpx = block.Find("dpx")) {
    OCCMAP_ASSIGN_OR_RETURN(double v, dpx->AsDouble());
    const double expected = p.dx_mm * p.Ncx / p.Nfx;
    if (std::abs(v - expected) > 1e-9 * std::max(1.0, std::abs(expected))) {
      return dpx->Error(fmt::format("expected dx * Ncx / Nfx = {}, found {}", expected, v));
    }
  }
  if (auto dpy = block.Find("dpy")) {
    OCCMAP_ASSIGN_OR_RETURN(double v, dpy->AsDouble());
    if (std::abs(v - p.dy_mm) > 1e-9 * std::max(1.0, p.dy_mm)) {
      return dpy->Error(fmt::format("expected dy = {}, found {}", p.dy_mm, v));
    }
  }
  for (int i = 0; i < 9; ++i) {
    const std::string key = fmt::format("r{}", i + 1);
    if (auto r = block.Find(key)) {
      OCCMAP_ASSIGN_OR_RETURN(double v, r->AsDouble());
      const double expected = p.cam_from_world_rotation(i / 3, i % 3);
      if (std::abs(v - expected) > 1e-9) {
        return r->Error(fmt::format("expected {:.17g} from Rx, Ry, Rz, found {:.17g}", expected, v));
      }
    }
  }
  // The camera's centre in the world, -R^T T (file units): documented as checked, now checked.
  if (auto centre = block.Find("camera_centre_world")) {
    OCCMAP_ASSIGN_OR_RETURN(std::vector<double> c, centre->AsDoubles(3));
    const Eigen::Vector3d expected = -(p.cam_from_world_rotation.transpose() * Eigen::Vector3d(tx, ty, tz));
    const Eigen::Vector3d found(c[0], c[1], c[2]);
    // The terrace file prints it to 1e-9 mm; 1e-6 of its size leaves room for any printing.
    if ((found - expected).norm() > 1e-6 * std::max(1.0, expected.norm())) {
      return centre->Error(fmt::format("expected -R^T T = [{:.9f}, {:.9f}, {:.9f}] from Rx, Ry, Rz, Tx, Ty, Tz, "
                                       "found [{}, {}, {}]",
                                       expected.x(), expected.y(), expected.z(), c[0], c[1], c[2]));
    }
  }
  OCCMAP_RETURN_IF_ERROR(p.Validate().WithContext(block.Where()));
  return p;
}

Status WriteTsaiYaml(const TsaiParameters& p, double rx, double ry, double rz, const std::string& camera,
                     const fs::path& path, double metres_per_unit) {
  const Eigen::Vector3d t = p.cam_from_world_translation_m / metres_per_unit;
  std::string indent = camera.empty() ? "" : "  ";
  std::string out = camera.empty() ? "" : camera + ":\n";
  auto line = [&](const char* key, double v) { out += fmt::format("{}{}: {:.17g}\n", indent, key, v); };
  out += fmt::format("{}image_width: {}\n{}image_height: {}\n", indent, p.image_size.width, indent,
                     p.image_size.height);
  line("Ncx", p.Ncx);
  line("Nfx", p.Nfx);
  line("dx", p.dx_mm);
  line("dy", p.dy_mm);
  line("Cx", p.Cx_px);
  line("Cy", p.Cy_px);
  line("sx", p.sx);
  line("f", p.f_mm);
  line("kappa1", p.kappa1_per_mm2);
  line("Tx", t.x());
  line("Ty", t.y());
  line("Tz", t.z());
  line("Rx", rx);
  line("Ry", ry);
  line("Rz", rz);
  return WriteFileAtomic(path, out);
}

}  // namespace occmap
