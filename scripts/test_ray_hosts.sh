#!/usr/bin/env bash
# mimicgen_rs.ray across two hosts, made on this machine from Linux network namespaces: a Ray head
# (10.77.0.1, CPU 0) and a worker node (10.77.0.2, CPU 1), joined by a veth pair and nothing else
# (no route out), each with 1 Ray CPU and its own private /tmp and /dev/shm (tmpfs in its own
# mount namespace), so the nodes share no working directory, Ray session or object store files;
# only the virtual environment (and this checkout) stay visible, as a node image would.
# The driver runs on the head (scripts/ray_hosts.py):
#   test (default): shards run on both nodes, placed by the test (two on the worker node, the rest
#     on the head), and the worker node is lost while the second of its shards runs, after the
#     first came back: that shard holds its files until the loss, so the kill cannot miss it
#     whatever Ray's scheduler does. The merged dataset must equal the single-process run with
#     the same seed (demos, arrays, failed attempts). Twice, on a fresh cluster each time: the node
#     "killed" (SIGKILL to every process in its namespace) and the node "vanished" (its link down,
#     then the same SIGKILL: the head hears nothing more from it, as when a machine dies).
#   --bench: wall time and attempts/s for 1, 2, 4 and 8 shards of one run (nobody killed).
# Needs root (ip netns, mount). Usage, with a Python that has the mimicgen_rs wheel and ray:
#   bash scripts/test_ray_hosts.sh /path/to/venv/bin/python [--bench [--attempts N]]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
root="$(cd "$here/.." && pwd)"

die() { echo "test_ray_hosts: FAILED: $*" >&2; exit 1; }
say() { echo "test_ray_hosts: $*" >&2; }

[ $# -ge 1 ] || die "usage: $0 PYTHON [--bench [--attempts N]] (PYTHON: a venv's python with the mimicgen_rs wheel and ray)"
python="$1"; shift
[ "$(id -u)" -eq 0 ] || die "needs root to make network namespaces (ip netns) and mounts"
[ -x "$python" ] || die "$python is not an executable Python"
# The venv's own path, symlinks kept: its python is a link to the base interpreter.
venv="$(cd "$(dirname "$python")/.." && pwd)"
"$python" -c "import mimicgen_rs, ray" || die "$python cannot import mimicgen_rs and ray"
for tool in ip unshare nsenter taskset; do
  command -v "$tool" >/dev/null || die "$tool not found (iproute2, util-linux)"
done
[ "$(nproc)" -ge 2 ] || say "only $(nproc) CPU: both nodes share it"

head_ns="mgray-head-$$"
worker_ns="mgray-worker-$$"
head_ip=10.77.0.1
worker_ip=10.77.0.2
port=6379
head_pid=""
logs="$(mktemp -d)"

stop_nodes() {
  local ns pids
  for ns in "$worker_ns" "$head_ns"; do
    pids="$(ip netns pids "$ns" 2>/dev/null || true)"
    # shellcheck disable=SC2086 # one pid per word
    [ -n "$pids" ] && kill -9 $pids 2>/dev/null || true
  done
  for _ in $(seq 50); do
    [ -z "$(ip netns pids "$worker_ns" 2>/dev/null)$(ip netns pids "$head_ns" 2>/dev/null)" ] && return
    sleep 0.1
  done
}

cleanup() {
  local ns
  stop_nodes
  for ns in "$worker_ns" "$head_ns"; do
    ip netns del "$ns" 2>/dev/null || true
  done
  # Left in this namespace only when the script stopped before moving it.
  ip link del "mgh$$" 2>/dev/null || true
  rm -rf "$logs"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

say "network namespaces $head_ns ($head_ip) and $worker_ns ($worker_ip)"
if ! ip netns add "$head_ns" || ! ip netns add "$worker_ns"; then
  die "cannot create network namespaces with 'ip netns add': this test needs root and network namespaces (in a container: CAP_SYS_ADMIN)"
fi
ip link add "mgh$$" type veth peer name "mgw$$" || die "cannot create a veth pair (kernel module veth?)"
ip link set "mgh$$" netns "$head_ns"
ip link set "mgw$$" netns "$worker_ns"
ip -n "$head_ns" addr add "$head_ip/24" dev "mgh$$"
ip -n "$worker_ns" addr add "$worker_ip/24" dev "mgw$$"
for ns in "$head_ns" "$worker_ns"; do
  ip -n "$ns" link set lo up
done
ip -n "$head_ns" link set "mgh$$" up
ip -n "$worker_ns" link set "mgw$$" up

# Runs inside a node's namespaces: private tmpfs on /tmp and /dev/shm; the venv and this checkout,
# when they live under /tmp, are carried across (bind-mounted to a staging tmpfs on /mnt, then
# moved onto the same paths in the new /tmp), so a node sees nothing else of the host's /tmp.
# shellcheck disable=SC2016 # expanded by the node's bash
node_setup='
set -euo pipefail
cpu="$1"; shift
mount -t tmpfs -o size=16m mgray-stage /mnt
keep=()
for p in "$VENV" "$ROOT"; do
  case "$p" in /tmp/*) mkdir "/mnt/${#keep[@]}"; mount --bind "$p" "/mnt/${#keep[@]}"; keep+=("$p");; esac
done
mount -t tmpfs -o size=2g mgray-tmp /tmp
mount -t tmpfs -o size=1g mgray-shm /dev/shm
for i in "${!keep[@]}"; do mkdir -p "${keep[$i]}"; mount --move "/mnt/$i" "${keep[$i]}"; done
umount /mnt
mkdir /tmp/node
cd /tmp/node
exec taskset -c "$cpu" "$@"
'
# Fast failure detection. The GCS declares a node dead after 3 missed health checks 300 ms apart
# (Ray's defaults: 5, 3 s apart). A task whose host vanished (no connection reset comes back) fails
# only when its owner's gRPC keepalive gives up on the connection, whatever the GCS says: 1 s + 1 s
# here, Ray's defaults 300 s + 120 s (the vanished case then waits 7 minutes).
export RAY_health_check_initial_delay_ms=0 RAY_health_check_period_ms=300 RAY_health_check_timeout_ms=300 \
  RAY_health_check_failure_threshold=3 RAY_grpc_client_keepalive_time_ms=1000 RAY_grpc_client_keepalive_timeout_ms=1000 \
  RAY_USAGE_STATS_ENABLED=0 HDF5_USE_FILE_LOCKING=FALSE
# Token authentication, as Ray asks for across hosts: a fresh token for this cluster, given to every
# node and the driver (RAY_AUTH_MODE set, so a token left in ~/.ray by a local ray.init() does not
# decide it).
RAY_AUTH_TOKEN="$("$python" -c 'import secrets; print(secrets.token_hex(32))')"
export RAY_AUTH_MODE=token RAY_AUTH_TOKEN
export VENV="$venv" ROOT="$root"
# Each node on its own core when there are two.
worker_cpu=1
[ "$(nproc)" -ge 2 ] || worker_cpu=0
ray_common=(--num-cpus=1 --num-gpus=0 --object-store-memory=200000000 --block --disable-usage-stats)
start_node() { # namespace cpu log ray-start-args...
  local ns="$1" cpu="$2" log="$3"; shift 3
  ip netns exec "$ns" unshare --mount --propagation private -- \
    bash -c "$node_setup" node "$cpu" "$python" -m ray.scripts.scripts start "${ray_common[@]}" "$@" >"$log" 2>&1 &
  # Killed on purpose later: no job-control notice for it.
  disown
}

start_cluster() {
  start_node "$head_ns" 0 "$logs/head.log" --head --node-ip-address="$head_ip" --port="$port" --include-dashboard=false
  head_pid=$!
  start_node "$worker_ns" "$worker_cpu" "$logs/worker.log" --address="$head_ip:$port" --node-ip-address="$worker_ip"
  say "Ray head (pid $head_pid, CPU 0) and worker node (pid $!, CPU $worker_cpu) starting"
  # The head's mount namespace is ready when its working directory exists there.
  for _ in $(seq 600); do
    nsenter --target "$head_pid" --mount -- test -d /tmp/node 2>/dev/null && return
    kill -0 "$head_pid" 2>/dev/null || { cat "$logs/head.log" >&2; die "the head node exited while starting"; }
    sleep 0.1
  done
  die "the head node's namespaces were not ready after 60 s"
}

# The driver runs on the head host: in the head's network and mount namespaces, on its CPU.
run_driver() { # driver-args...
  local status=0
  timeout 300 nsenter --target "$head_pid" --net --mount --wd -- taskset -c 0 \
    "$python" "$here/ray_hosts.py" --address "$head_ip:$port" --head-ip "$head_ip" --worker-ip "$worker_ip" "$@" || status=$?
  if [ "$status" -ne 0 ]; then
    say "the head's log:"; tail -n 30 "$logs/head.log" >&2 || true
    say "the worker node's log:"; tail -n 30 "$logs/worker.log" >&2 || true
    [ "$status" -eq 124 ] && die "the driver did not finish in 300 s"
    die "the driver exited with status $status"
  fi
}

kill_node="ip netns pids $worker_ns | xargs -r kill -9"
if [ "${1:-}" = "--bench" ]; then
  start_cluster
  run_driver --kill "$kill_node" "$@"
else
  # Two ways to lose the worker node, each on a fresh cluster: its processes killed (the host stays
  # up and its kernel resets their connections), then the host vanishing (its link down first, so
  # nothing more reaches the head, then its processes killed).
  for how in killed vanished; do
    say "== the worker node $how mid-run"
    start_cluster
    case "$how" in
      killed) run_driver --kill "$kill_node" --loss "$how" "$@" ;;
      vanished) run_driver --kill "ip -n $worker_ns link set mgw$$ down && $kill_node" --loss "$how" "$@" ;;
    esac
    stop_nodes
    ip -n "$worker_ns" link set "mgw$$" up
  done
fi
say "ok"
