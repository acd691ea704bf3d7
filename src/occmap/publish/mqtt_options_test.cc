#include "occmap/publish/mqtt_options.h"

#include <gtest/gtest.h>

#include <sys/stat.h>

#include <filesystem>
#include <fstream>

#include "occmap/publish/mqtt_topics.h"
#include "occmap/util/testing.h"

namespace occmap {
namespace {

TEST(ParseMqttUrl, ReadsHostAndPort) {
  EXPECT_EQ(*ParseMqttUrl("mqtt://127.0.0.1:1884", "--mqtt"), (MqttBroker{"127.0.0.1", 1884}));
  EXPECT_EQ(*ParseMqttUrl("mqtt://broker.local", "--mqtt"), (MqttBroker{"broker.local", 1883}));
  EXPECT_EQ(*ParseMqttUrl("mqtt://broker/", "--mqtt"), (MqttBroker{"broker", 1883}));
  EXPECT_EQ(*ParseMqttUrl("mqtt://[::1]:1900", "--mqtt"), (MqttBroker{"::1", 1900}));
}

TEST(ParseMqttUrl, MalformedUrlsSayWhatWasExpected) {
  const struct {
    const char* url;
    const char* message;
  } cases[] = {
      {"127.0.0.1:1883", "--mqtt: expected mqtt://HOST[:PORT], found '127.0.0.1:1883'"},
      {"http://x", "--mqtt: expected mqtt://HOST[:PORT], found 'http://x'"},
      {"mqtts://x:8883", "--mqtt: expected mqtt://HOST[:PORT] (TLS is not supported), found 'mqtts://x:8883'"},
      {"mqtt://", "--mqtt: expected mqtt://HOST[:PORT] (a host), found 'mqtt://'"},
      {"mqtt://:1883", "--mqtt: expected mqtt://HOST[:PORT] (a host), found 'mqtt://:1883'"},
      {"mqtt://x:", "--mqtt: expected mqtt://HOST[:PORT] (a port after ':'), found 'mqtt://x:'"},
      {"mqtt://x:0", "--mqtt: expected mqtt://HOST[:PORT] (a port in 1..65535), found 'mqtt://x:0'"},
      {"mqtt://x:65536", "--mqtt: expected mqtt://HOST[:PORT] (a port in 1..65535), found 'mqtt://x:65536'"},
      {"mqtt://x:18a", "--mqtt: expected mqtt://HOST[:PORT] (a port in 1..65535), found 'mqtt://x:18a'"},
      {"mqtt://x/topic", "--mqtt: expected mqtt://HOST[:PORT] (no path), found 'mqtt://x/topic'"},
      {"mqtt://u:p@x", "--mqtt: expected mqtt://HOST[:PORT] (a login goes in username and password_file), found 'mqtt://u:p@x'"},
      {"mqtt://[::1", "--mqtt: expected mqtt://HOST[:PORT] (an IPv6 address ends with ']'), found 'mqtt://[::1'"},
  };
  for (const auto& c : cases) {
    const Result<MqttBroker> r = ParseMqttUrl(c.url, "--mqtt");
    ASSERT_FALSE(r.ok()) << c.url;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidInput);
    EXPECT_EQ(r.status().message(), c.message);
  }
}

TEST(TopicSlug, KeepsLowercaseLettersDigitsAndDashes) {
  EXPECT_EQ(TopicSlug("Door West"), "door_west");
  EXPECT_EQ(TopicSlug("a/b+#"), "a_b__");
  EXPECT_EQ(TopicSlug(""), "_");
  EXPECT_EQ(UniqueSlugs({"Door", "door", "DOOR", "x"}), (std::vector<std::string>{"door", "door_2", "door_3", "x"}));
}

TEST(ResolveMqttDefaults, PrefixAndClientIdFromTheSiteName) {
  MqttOptions o;
  ResolveMqttDefaults("Lab 2", o);
  EXPECT_EQ(o.topic_prefix, "occmap/lab_2");
  EXPECT_EQ(o.client_id, "occmap-lab_2");
  o.topic_prefix = "site/a";
  ResolveMqttDefaults("other", o);
  EXPECT_EQ(o.topic_prefix, "site/a") << "given values stay";
}

Result<MqttOptions> Parse(const std::string& yaml) {
  OCCMAP_ASSIGN_OR_RETURN(YamlField root, ParseYaml(yaml, "site.yaml"));
  OCCMAP_ASSIGN_OR_RETURN(YamlField outputs, root.Get("outputs"));
  OCCMAP_ASSIGN_OR_RETURN(YamlField mqtt, outputs.Get("mqtt"));
  return ParseMqttOptions(mqtt, std::filesystem::temp_directory_path());
}

TEST(ParseMqttOptions, ReadsEveryKey) {
  const std::filesystem::path password = std::filesystem::temp_directory_path() / "occmap-mqtt-options-test.secret";
  std::ofstream(password) << "s3cret\nignored\n";
  const Result<MqttOptions> o = Parse(R"(outputs:
  mqtt:
    url: mqtt://10.0.0.2:1999
    topic_prefix: building/occmap
    client_id: occ-1
    username: occmap
    password_file: occmap-mqtt-options-test.secret
    keepalive_s: 20
    stats_every_s: 2.5
    discovery: false
    discovery_prefix: ha
)");
  ASSERT_TRUE(o.ok()) << o.status().ToString();
  EXPECT_EQ(o->broker, (MqttBroker{"10.0.0.2", 1999}));
  EXPECT_EQ(o->topic_prefix, "building/occmap");
  EXPECT_EQ(o->client_id, "occ-1");
  EXPECT_EQ(o->username, "occmap");
  EXPECT_EQ(o->password_file, password);
  EXPECT_EQ(o->keepalive_s, 20);
  EXPECT_EQ(o->stats_every_s, 2.5);
  EXPECT_FALSE(o->discovery);
  EXPECT_EQ(o->discovery_prefix, "ha");
  EXPECT_EQ(*ReadMqttPassword(password), "s3cret");
  std::filesystem::remove(password);
}

// Issue 39: a password file that is a FIFO, a folder or a loop of links was "file not found".
TEST(ParseMqttOptions, APasswordFileThatIsNotAFileIsSaidAsWhatItIs) {
  testing::TempDir dir;
  ASSERT_EQ(::mkfifo((dir / "fifo").c_str(), 0600), 0);
  std::filesystem::create_directory(dir / "folder");
  std::filesystem::create_symlink(dir / "loop-b", dir / "loop-a");
  std::filesystem::create_symlink(dir / "loop-a", dir / "loop-b");
  const struct {
    const char* name;
    const char* found;
  } cases[] = {
      {"fifo", "expected a regular file, found a FIFO"},
      {"folder", "expected a file, found a directory"},
      {"loop-a", "cannot be read: Too many levels of symbolic links (a loop of symbolic links)"},
  };
  for (const auto& c : cases) {
    const std::string path = (dir / c.name).string();
    const Result<MqttOptions> r =
        Parse("outputs:\n  mqtt:\n    url: mqtt://x\n    username: u\n    password_file: " + path);
    ASSERT_FALSE(r.ok()) << c.name;
    EXPECT_EQ(r.status().code(), StatusCode::kInvalidInput) << c.name;
    EXPECT_EQ(r.status().message(), "site.yaml:5: outputs.mqtt.password_file: '" + path + "': " + c.found);
  }
}

TEST(ParseMqttOptions, MalformedBlocksGiveLocatedMessages) {
  const struct {
    const char* yaml;
    const char* message;
  } cases[] = {
      {"outputs:\n  mqtt: mqtt://x", "site.yaml:2: outputs.mqtt: expected a map with at least url (mqtt://HOST[:PORT])"},
      {"outputs:\n  mqtt:\n    topic_prefix: a", "site.yaml:3: outputs.mqtt: missing required field 'url'"},
      {"outputs:\n  mqtt:\n    url: http://x", "site.yaml:3: outputs.mqtt.url: expected mqtt://HOST[:PORT], found 'http://x'"},
      {"outputs:\n  mqtt:\n    url: mqtt://x\n    urls: y", "site.yaml:4: outputs.mqtt: unknown field 'urls' (did you mean 'url'?)"},
      {"outputs:\n  mqtt:\n    url: mqtt://x\n    topic_prefix: /occmap",
       "site.yaml:4: outputs.mqtt.topic_prefix: expected no '/' at either end, found '/occmap'"},
      {"outputs:\n  mqtt:\n    url: mqtt://x\n    topic_prefix: a/#",
       "site.yaml:4: outputs.mqtt.topic_prefix: expected no MQTT wildcard ('+' or '#'), found 'a/#'"},
      {"outputs:\n  mqtt:\n    url: mqtt://x\n    topic_prefix: a//b",
       "site.yaml:4: outputs.mqtt.topic_prefix: expected no empty topic level ('//'), found 'a//b'"},
      {"outputs:\n  mqtt:\n    url: mqtt://x\n    password_file: p", "site.yaml:4: outputs.mqtt.password_file: expected a username with it"},
      {"outputs:\n  mqtt:\n    url: mqtt://x\n    username: u\n    password_file: /nonexistent/occmap-pw",
       "site.yaml:5: outputs.mqtt.password_file: file not found: '/nonexistent/occmap-pw'"},
      {"outputs:\n  mqtt:\n    url: mqtt://x\n    keepalive_s: 2",
       "site.yaml:4: outputs.mqtt.keepalive_s: expected an integer in [5, 65535], found 2"},
      {"outputs:\n  mqtt:\n    url: mqtt://x\n    stats_every_s: 0",
       "site.yaml:4: outputs.mqtt.stats_every_s: expected a number in (0, 3600], found 0"},
      {"outputs:\n  mqtt:\n    url: mqtt://x\n    discovery: maybe",
       "site.yaml:4: outputs.mqtt.discovery: expected true or false, found 'maybe'"},
      {"outputs:\n  mqtt:\n    url: mqtt://x\n    client_id: ''", "site.yaml:4: outputs.mqtt.client_id: expected a non-empty client id"},
  };
  for (const auto& c : cases) {
    const Result<MqttOptions> r = Parse(c.yaml);
    ASSERT_FALSE(r.ok()) << c.yaml;
    EXPECT_EQ(r.status().message(), c.message) << c.yaml;
  }
}

}  // namespace
}  // namespace occmap
