#include "occmap/publish/mqtt_topics.h"

#include <set>

#include "occmap/publish/mqtt_options.h"

namespace occmap {

std::vector<std::string> UniqueSlugs(const std::vector<std::string>& names) {
  std::vector<std::string> slugs;
  std::set<std::string> used;
  for (const std::string& name : names) {
    const std::string base = TopicSlug(name);
    std::string slug = base;
    for (int n = 2; used.contains(slug); ++n) slug = base + "_" + std::to_string(n);
    used.insert(slug);
    slugs.push_back(slug);
  }
  return slugs;
}

MqttTopics MqttTopics::For(const std::string& prefix, const std::vector<std::string>& zones,
                           const std::vector<std::string>& lines, const std::vector<std::string>& cameras) {
  MqttTopics t;
  t.available = prefix + "/available";
  t.tracks = prefix + "/tracks";
  t.events = prefix + "/events";
  t.stats = prefix + "/stats";
  t.people = prefix + "/people";
  t.run = prefix + "/run";
  t.run_attributes = prefix + "/run/attributes";
  t.map = prefix + "/map";
  t.zone_slugs = UniqueSlugs(zones);
  t.line_slugs = UniqueSlugs(lines);
  for (const std::string& z : t.zone_slugs) {
    t.zone_count.push_back(prefix + "/zones/" + z + "/count");
    t.zone_occupied.push_back(prefix + "/zones/" + z + "/occupied");
  }
  for (const std::string& l : t.line_slugs) {
    t.line_in.push_back(prefix + "/lines/" + l + "/in");
    t.line_out.push_back(prefix + "/lines/" + l + "/out");
  }
  t.camera_slugs = UniqueSlugs(cameras);
  for (const std::string& c : t.camera_slugs) {
    t.camera_state.push_back(prefix + "/cameras/" + c + "/state");
    t.camera_fps.push_back(prefix + "/cameras/" + c + "/fps");
  }
  return t;
}

std::vector<std::string> MqttTopics::Retained() const {
  std::vector<std::string> out = {available, people, run, run_attributes, map};
  for (const auto* list : {&zone_count, &zone_occupied, &line_in, &line_out, &camera_state, &camera_fps}) {
    out.insert(out.end(), list->begin(), list->end());
  }
  return out;
}

}  // namespace occmap
