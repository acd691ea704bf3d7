// Test helpers: a real mosquitto broker on 127.0.0.1 with an ephemeral port and a generated
// config (stopped by its PID), and a subscriber that records what it receives.
//
//   TestBroker broker;  ASSERT_TRUE(broker.Start()) << broker.error();
//   TestSubscriber sub(broker.port(), "occmap/#");  ASSERT_TRUE(sub.WaitSubscribed());
//   EXPECT_TRUE(sub.WaitFor("occmap/lab/available", "online"));
#pragma once

#include <arpa/inet.h>
#include <fcntl.h>
#include <mosquitto.h>
#include <netinet/in.h>
#include <signal.h>
#include <spawn.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <condition_variable>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

extern char** environ;

namespace occmap::testing {

inline constexpr const char* kMosquittoBinary = "/usr/sbin/mosquitto";

// A free TCP port on 127.0.0.1 (bound to port 0, read back, released).
inline int FreeLoopbackPort() {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = 0;
  socklen_t len = sizeof(addr);
  int port = -1;
  if (::bind(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) == 0 &&
      ::getsockname(fd, reinterpret_cast<sockaddr*>(&addr), &len) == 0) {
    port = ntohs(addr.sin_port);
  }
  ::close(fd);
  return port;
}

inline bool PortAccepts(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM, 0);
  sockaddr_in addr{};
  addr.sin_family = AF_INET;
  addr.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  addr.sin_port = htons(static_cast<uint16_t>(port));
  const bool ok = ::connect(fd, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)) == 0;
  ::close(fd);
  return ok;
}

class TestBroker {
 public:
  // extra_config: lines added to the generated config ("allow_anonymous false" refuses every
  // login).
  explicit TestBroker(int port = 0, std::string extra_config = "")
      : port_(port > 0 ? port : FreeLoopbackPort()), extra_config_(std::move(extra_config)) {
    dir_ = std::filesystem::temp_directory_path() / ("occmap-broker-" + std::to_string(::getpid()) + "-" + std::to_string(port_));
  }
  ~TestBroker() {
    Stop();
    std::error_code ec;
    std::filesystem::remove_all(dir_, ec);
  }

  // Writes the config, starts mosquitto and waits (up to 5 s) until the port accepts.
  bool Start() {
    if (!std::filesystem::exists(kMosquittoBinary)) {
      error_ = std::string(kMosquittoBinary) + " not found: install mosquitto (scripts/install-deps.sh)";
      return false;
    }
    std::filesystem::create_directories(dir_);
    const std::filesystem::path conf = dir_ / "mosquitto.conf";
    // The log goes to stderr, redirected here: run as root, mosquitto drops to its own user,
    // who could not open a log file in this folder.
    const bool anonymous = extra_config_.find("allow_anonymous") == std::string::npos;
    std::ofstream(conf) << "listener " << port_ << " 127.0.0.1\n"
                        << (anonymous ? "allow_anonymous true\n" : "") << "persistence false\n"
                        << "log_dest stderr\n"
                        << extra_config_ << "\n";
    const std::string conf_text = conf.string();
    const std::string log_text = (dir_ / "broker.log").string();
    const char* argv[] = {kMosquittoBinary, "-c", conf_text.c_str(), nullptr};
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 2, log_text.c_str(), O_WRONLY | O_CREAT | O_APPEND, 0644);
    const int spawned = posix_spawn(&pid_, kMosquittoBinary, &actions, nullptr, const_cast<char* const*>(argv), environ);
    posix_spawn_file_actions_destroy(&actions);
    if (spawned != 0) {
      error_ = "posix_spawn failed";
      pid_ = -1;
      return false;
    }
    for (int k = 0; k < 500; ++k) {
      if (PortAccepts(port_)) return true;
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        error_ = "mosquitto exited at start (see " + (dir_ / "broker.log").string() + ")";
        return false;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    error_ = "mosquitto did not listen on port " + std::to_string(port_) + " within 5 s";
    return false;
  }

  // Stops the broker by its PID (SIGTERM, then SIGKILL after 5 s) and reaps it.
  void Stop() {
    if (pid_ <= 0) return;
    ::kill(pid_, SIGTERM);
    for (int k = 0; k < 500; ++k) {
      int status = 0;
      if (::waitpid(pid_, &status, WNOHANG) == pid_) {
        pid_ = -1;
        return;
      }
      std::this_thread::sleep_for(std::chrono::milliseconds(10));
    }
    ::kill(pid_, SIGKILL);
    ::waitpid(pid_, nullptr, 0);
    pid_ = -1;
  }

  int port() const { return port_; }
  const std::string& error() const { return error_; }

 private:
  int port_ = 0;
  std::string extra_config_;
  pid_t pid_ = -1;
  std::filesystem::path dir_;
  std::string error_;
};

struct ReceivedMessage {
  std::string topic, payload;
  bool retain = false;
};

// A libmosquitto subscriber on its own network thread, recording every message.
class TestSubscriber {
 public:
  TestSubscriber(int port, std::string filter) : filter_(std::move(filter)) {
    mosquitto_lib_init();
    mosq_ = mosquitto_new(nullptr, true, this);
    mosquitto_connect_callback_set(mosq_, [](mosquitto* m, void* self, int rc) {
      auto* s = static_cast<TestSubscriber*>(self);
      if (rc == 0) mosquitto_subscribe(m, nullptr, s->filter_.c_str(), 1);
    });
    mosquitto_subscribe_callback_set(mosq_, [](mosquitto*, void* self, int, int, const int*) {
      auto* s = static_cast<TestSubscriber*>(self);
      std::lock_guard<std::mutex> lock(s->mutex_);
      s->subscribed_ = true;
      s->cv_.notify_all();
    });
    mosquitto_publish_callback_set(mosq_, [](mosquitto*, void* self, int mid) {
      auto* s = static_cast<TestSubscriber*>(self);
      std::lock_guard<std::mutex> lock(s->mutex_);
      s->published_mid_ = mid;
      s->cv_.notify_all();
    });
    mosquitto_message_callback_set(mosq_, [](mosquitto*, void* self, const mosquitto_message* m) {
      auto* s = static_cast<TestSubscriber*>(self);
      std::lock_guard<std::mutex> lock(s->mutex_);
      s->messages_.push_back({m->topic, std::string(static_cast<const char*>(m->payload), static_cast<size_t>(m->payloadlen)),
                              m->retain});
      s->cv_.notify_all();
    });
    mosquitto_connect_async(mosq_, "127.0.0.1", port, 30);
    mosquitto_loop_start(mosq_);
  }
  ~TestSubscriber() {
    mosquitto_disconnect(mosq_);
    mosquitto_loop_stop(mosq_, false);
    mosquitto_destroy(mosq_);
  }

  bool WaitSubscribed(std::chrono::milliseconds timeout = std::chrono::seconds(5)) {
    std::unique_lock<std::mutex> lock(mutex_);
    return cv_.wait_for(lock, timeout, [&] { return subscribed_; });
  }
  // Waits until a message arrived on each of the topics.
  bool WaitForAll(const std::vector<std::string>& topics, std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    for (const std::string& t : topics) {
      if (!WaitFor(t, "", 0, timeout)) return false;
    }
    return true;
  }
  // Waits for a message on `topic` (with `payload` unless empty) received after index `from`.
  bool WaitFor(const std::string& topic, const std::string& payload = "", size_t from = 0,
               std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    std::unique_lock<std::mutex> lock(mutex_);
    return cv_.wait_for(lock, timeout, [&] {
      for (size_t k = from; k < messages_.size(); ++k) {
        if (messages_[k].topic == topic && (payload.empty() || messages_[k].payload == payload)) return true;
      }
      return false;
    });
  }
  // Waits for an empty payload on `topic` (a retained topic cleared).
  bool WaitForCleared(const std::string& topic, std::chrono::milliseconds timeout = std::chrono::seconds(10)) {
    std::unique_lock<std::mutex> lock(mutex_);
    return cv_.wait_for(lock, timeout, [&] {
      for (const ReceivedMessage& m : messages_) {
        if (m.topic == topic && m.payload.empty()) return true;
      }
      return false;
    });
  }
  // Publishes (QoS 1) and waits until the broker has it.
  bool Publish(const std::string& topic, const std::string& payload, bool retain = false) {
    int mid = 0;
    {
      std::lock_guard<std::mutex> lock(mutex_);
      published_mid_ = -1;
    }
    if (mosquitto_publish(mosq_, &mid, topic.c_str(), static_cast<int>(payload.size()), payload.data(), 1, retain) !=
        MOSQ_ERR_SUCCESS) {
      return false;
    }
    std::unique_lock<std::mutex> lock(mutex_);
    return cv_.wait_for(lock, std::chrono::seconds(5), [&] { return published_mid_ == mid; });
  }
  std::vector<ReceivedMessage> Messages() {
    std::lock_guard<std::mutex> lock(mutex_);
    return messages_;
  }
  // The messages on `topic`; live_only: without those delivered as retained on subscribing.
  std::vector<ReceivedMessage> On(const std::string& topic, bool live_only = false) {
    std::vector<ReceivedMessage> out;
    for (const ReceivedMessage& m : Messages()) {
      if (m.topic == topic && !(live_only && m.retain)) out.push_back(m);
    }
    return out;
  }

 private:
  std::string filter_;
  mosquitto* mosq_ = nullptr;
  std::mutex mutex_;
  std::condition_variable cv_;
  bool subscribed_ = false;
  int published_mid_ = -1;
  std::vector<ReceivedMessage> messages_;
};

}  // namespace occmap::testing
