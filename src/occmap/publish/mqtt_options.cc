#include "occmap/publish/mqtt_options.h"

#include <fmt/core.h>

#include <charconv>
#include <system_error>

#include "occmap/util/file_util.h"
#include "occmap/util/safe_files.h"

namespace occmap {
namespace {

// What is wrong with a topic prefix, or "" when it is fine.
std::string TopicPrefixProblem(std::string_view prefix) {
  if (prefix.empty()) return "expected a non-empty topic prefix";
  if (prefix.find_first_of("+#") != std::string_view::npos) return "expected no MQTT wildcard ('+' or '#')";
  if (prefix.front() == '/' || prefix.back() == '/') return "expected no '/' at either end";
  if (prefix.find("//") != std::string_view::npos) return "expected no empty topic level ('//')";
  if (prefix.front() == '$') return "expected no leading '$' (the broker's own topics)";
  for (const char ch : prefix) {
    if (static_cast<unsigned char>(ch) < 0x20) return "expected no control characters";
  }
  return "";
}

std::string PrefixedMessage(std::string_view where, std::string_view what) {
  return where.empty() ? std::string(what) : fmt::format("{}: {}", where, what);
}

}  // namespace

Result<MqttBroker> ParseMqttUrl(std::string_view url, std::string_view where) {
  auto bad = [&](std::string_view why) {
    return InvalidInput(PrefixedMessage(
        where, fmt::format("expected mqtt://HOST[:PORT]{}, found '{}'", why.empty() ? "" : fmt::format(" ({})", why), url)));
  };
  constexpr std::string_view kScheme = "mqtt://";
  if (url.starts_with("mqtts://") || url.starts_with("ssl://")) return bad("TLS is not supported");
  if (!url.starts_with(kScheme)) return bad("");
  std::string_view rest = url.substr(kScheme.size());
  if (rest.ends_with('/')) rest.remove_suffix(1);
  if (rest.find('@') != std::string_view::npos) return bad("a login goes in username and password_file");
  if (rest.find_first_of("/?#") != std::string_view::npos) return bad("no path");
  MqttBroker broker;
  std::string_view port_text;
  if (rest.starts_with('[')) {  // [IPv6]:port
    const size_t close = rest.find(']');
    if (close == std::string_view::npos) return bad("an IPv6 address ends with ']'");
    broker.host = std::string(rest.substr(1, close - 1));
    std::string_view after = rest.substr(close + 1);
    if (!after.empty()) {
      if (after.front() != ':') return bad("");
      port_text = after.substr(1);
      if (port_text.empty()) return bad("a port after ':'");
    }
  } else {
    const size_t colon = rest.find(':');
    broker.host = std::string(rest.substr(0, colon));
    if (colon != std::string_view::npos) {
      port_text = rest.substr(colon + 1);
      if (port_text.empty()) return bad("a port after ':'");
    }
  }
  if (broker.host.empty()) return bad("a host");
  if (!port_text.empty()) {
    int port = 0;
    const auto [end, ec] = std::from_chars(port_text.data(), port_text.data() + port_text.size(), port);
    if (ec != std::errc() || end != port_text.data() + port_text.size() || port < 1 || port > 65535) {
      return bad("a port in 1..65535");
    }
    broker.port = port;
  }
  return broker;
}

std::string TopicSlug(std::string_view name) {
  std::string slug;
  for (const char ch : name) {
    const char lower = (ch >= 'A' && ch <= 'Z') ? static_cast<char>(ch - 'A' + 'a') : ch;
    const bool ok = (lower >= 'a' && lower <= 'z') || (lower >= '0' && lower <= '9') || lower == '_' || lower == '-';
    slug += ok ? lower : '_';
  }
  return slug.empty() ? "_" : slug;
}

void ResolveMqttDefaults(std::string_view site_name, MqttOptions& options) {
  const std::string slug = TopicSlug(site_name.empty() ? "site" : site_name);
  if (options.topic_prefix.empty()) options.topic_prefix = "occmap/" + slug;
  if (options.client_id.empty()) options.client_id = "occmap-" + slug;
}

Status MqttOptions::Validate() const {
  if (broker.host.empty()) return InvalidInput("mqtt: expected a broker host");
  if (broker.port < 1 || broker.port > 65535) return InvalidInput(fmt::format("mqtt: expected a port in 1..65535, found {}", broker.port));
  if (!topic_prefix.empty()) {
    if (std::string p = TopicPrefixProblem(topic_prefix); !p.empty()) {
      return InvalidInput(fmt::format("mqtt.topic_prefix: {}, found '{}'", p, topic_prefix));
    }
  }
  if (std::string p = TopicPrefixProblem(discovery_prefix); !p.empty()) {
    return InvalidInput(fmt::format("mqtt.discovery_prefix: {}, found '{}'", p, discovery_prefix));
  }
  if (!password_file.empty() && username.empty()) return InvalidInput("mqtt.password_file: expected a username with it");
  if (keepalive_s < 5 || keepalive_s > 65535) {
    return InvalidInput(fmt::format("mqtt.keepalive_s: expected an integer in [5, 65535], found {}", keepalive_s));
  }
  if (!(stats_every_s > 0) || !(stats_every_s <= 3600)) {
    return InvalidInput(fmt::format("mqtt.stats_every_s: expected a number in (0, 3600], found {}", stats_every_s));
  }
  return Status::Ok();
}

Result<MqttOptions> ParseMqttOptions(const YamlField& field, const std::filesystem::path& site_dir) {
  if (!field.IsMap()) return field.Error("expected a map with at least url (mqtt://HOST[:PORT])");
  OCCMAP_RETURN_IF_ERROR(field.CheckKeys({"url", "topic_prefix", "client_id", "username", "password_file", "keepalive_s",
                                          "stats_every_s", "discovery", "discovery_prefix"}));
  MqttOptions options;
  OCCMAP_ASSIGN_OR_RETURN(YamlField url, field.Get("url"));
  OCCMAP_ASSIGN_OR_RETURN(std::string url_text, url.AsString());
  OCCMAP_ASSIGN_OR_RETURN(options.broker, ParseMqttUrl(url_text, url.Where()));
  if (auto f = field.Find("topic_prefix")) {
    OCCMAP_ASSIGN_OR_RETURN(options.topic_prefix, f->AsString());
    if (std::string p = TopicPrefixProblem(options.topic_prefix); !p.empty()) {
      return f->Error(fmt::format("{}, found '{}'", p, options.topic_prefix));
    }
  }
  if (auto f = field.Find("client_id")) {
    OCCMAP_ASSIGN_OR_RETURN(options.client_id, f->AsString());
    if (options.client_id.empty()) return f->Error("expected a non-empty client id");
  }
  OCCMAP_ASSIGN_OR_RETURN(options.username, field.GetString("username", ""));
  if (auto f = field.Find("password_file")) {
    OCCMAP_ASSIGN_OR_RETURN(std::string file, f->AsString());
    if (options.username.empty()) return f->Error("expected a username with it");
    options.password_file = ResolvePath(site_dir, file);
    // A FIFO, a folder or a loop of links is said as what it is, not "not found" (issue 39).
    if (Status s = CheckRegularFile(options.password_file); !s.ok()) return s.WithContext(f->Where());
  }
  if (auto f = field.Find("keepalive_s")) {
    OCCMAP_ASSIGN_OR_RETURN(int64_t k, f->AsInt());
    if (k < 5 || k > 65535) return f->Error(fmt::format("expected an integer in [5, 65535], found {}", k));
    options.keepalive_s = static_cast<int>(k);
  }
  if (auto f = field.Find("stats_every_s")) {
    OCCMAP_ASSIGN_OR_RETURN(double s, f->AsDouble());
    if (!(s > 0 && s <= 3600)) return f->Error(fmt::format("expected a number in (0, 3600], found {}", s));
    options.stats_every_s = s;
  }
  OCCMAP_ASSIGN_OR_RETURN(options.discovery, field.GetBool("discovery", true));
  if (auto f = field.Find("discovery_prefix")) {
    OCCMAP_ASSIGN_OR_RETURN(options.discovery_prefix, f->AsString());
    if (std::string p = TopicPrefixProblem(options.discovery_prefix); !p.empty()) {
      return f->Error(fmt::format("{}, found '{}'", p, options.discovery_prefix));
    }
  }
  OCCMAP_RETURN_IF_ERROR(options.Validate().WithContext(field.Where()));
  return options;
}

Result<std::string> ReadMqttPassword(const std::filesystem::path& password_file) {
  OCCMAP_ASSIGN_OR_RETURN(std::string text, ReadFileToString(password_file));
  const size_t end = text.find_first_of("\r\n");
  if (end != std::string::npos) text.resize(end);
  if (text.empty()) return InvalidInput(fmt::format("{}: expected a password on the first line, found an empty line", password_file.string()));
  return text;
}

}  // namespace occmap
