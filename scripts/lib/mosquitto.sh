# A mosquitto broker of a script's own, for the tests and benches that talk MQTT (sourced, not
# run): on 127.0.0.1 at a free port, a generated config and its log in the caller's folder,
# stopped by its PID (never by name: other brokers may be running).
#
#   source "$src/scripts/lib/mosquitto.sh"
#   mosquitto_start "$work" ["max_queued_messages 100000" ...] || exit 1   # $mosquitto_port, $mosquitto_pid
#   mosquitto_restart "$work" [PAUSE_S] || exit 1   # the same port and config, PAUSE_S after the stop
#   mosquitto_stop
#
# Needs /usr/sbin/mosquitto, mosquitto_pub and python3 (scripts/install-deps.sh installs them).

mosquitto_port=""
mosquitto_pid=""

# mosquitto_wait DIR: 0 once the broker answers a publish (5 s at most); else its log, and 1.
mosquitto_wait() {
  for _ in $(seq 100); do
    mosquitto_pub -h 127.0.0.1 -p "$mosquitto_port" -t occmap-test/probe -m x 2>/dev/null && return 0
    sleep 0.05
  done
  echo "FAIL the broker did not start (mosquitto on 127.0.0.1:$mosquitto_port):"
  cat "$1/broker.log"
  return 1
}

# mosquitto_launch DIR: mosquitto on DIR/mosquitto.conf, its log appended to DIR/broker.log.
mosquitto_launch() {
  /usr/sbin/mosquitto -c "$1/mosquitto.conf" 2>>"$1/broker.log" &
  mosquitto_pid=$!
  mosquitto_wait "$1"
}

# mosquitto_start DIR [CONFIG_LINE...]: a broker at a free port of 127.0.0.1 (anonymous, no
# persistence); CONFIG_LINEs are added to its config.
mosquitto_start() {
  local dir=$1
  shift
  mosquitto_port=$(python3 -c 'import socket; s = socket.socket(); s.bind(("127.0.0.1", 0)); print(s.getsockname()[1])')
  {
    echo "listener $mosquitto_port 127.0.0.1"
    echo "allow_anonymous true"
    echo "persistence false"
    echo "log_dest stderr"
    local line
    for line in "$@"; do echo "$line"; done
  } >"$dir/mosquitto.conf"
  : >"$dir/broker.log"
  mosquitto_launch "$dir"
}

# mosquitto_stop: the broker stopped (SIGTERM) and waited for.
mosquitto_stop() {
  if [ -n "$mosquitto_pid" ]; then
    kill "$mosquitto_pid" 2>/dev/null
    wait "$mosquitto_pid" 2>/dev/null
  fi
  mosquitto_pid=""
}

# mosquitto_restart DIR [PAUSE_S]: stopped, then (PAUSE_S later) started again on the same port
# with the same config: a broker restarted under its clients.
mosquitto_restart() {
  mosquitto_stop
  [ -n "${2:-}" ] && sleep "$2"
  mosquitto_launch "$1"
}
