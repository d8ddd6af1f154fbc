#!/usr/bin/env bash
# Load and faults against `instainpaint serve --scene statue`, as an attacker or an
# unlucky user would try them; prints the figures that docs/reliability.md records:
#   1. wrk, 64 connections for 30 s on /api/info and on a view image, while an edit job runs:
#      errors, latency percentiles, and whether the job still finishes;
#   2. slow clients (a request sent one byte a second): how long until the server drops them,
#      and /api/info's answer time meanwhile;
#   3. a client that disconnects in the middle of an upload: no job and no file left behind;
#   4. kill -9 during a job, then a restart: the killed job's output is never served;
#   5. a 16000 x 16000 PNG as the reference: the answer and the server's peak memory.
#
#   scripts/measure-serve-load.sh [--bin build/instainpaint] [--scene ../shared/data/statue]
#       [--seconds 30] [--connections 64]
# Needs wrk (Debian: apt-get install wrk; installed here when missing) and python3.
set -euo pipefail
BIN=build/instainpaint SCENE=../shared/data/statue SECONDS_=30 CONNECTIONS=64
while [ $# -gt 0 ]; do
  case "$1" in
    --bin) BIN=$2; shift 2 ;;
    --scene) SCENE=$2; shift 2 ;;
    --seconds) SECONDS_=$2; shift 2 ;;
    --connections) CONNECTIONS=$2; shift 2 ;;
    -h|--help) sed -n '2,14p' "$0"; exit 0 ;;
    *) echo "unknown argument $1 (see --help)" >&2; exit 2 ;;
  esac
done
command -v wrk > /dev/null || apt-get install -y -qq wrk > /dev/null
WORK=$(mktemp -d /tmp/serve-load.XXXXXX)
TOKEN=load-test-token
VIEW=IMG_2707
MASK=$SCENE/images_2/label/$VIEW.png
PID=""
trap '[ -n "$PID" ] && kill -9 "$PID" 2> /dev/null; rm -rf "$WORK"' EXIT

# start_server: serve in the background on a free port; sets PID, PORT, URL.
start_server() {
  "$BIN" serve --scene "$SCENE" --out "$WORK/out" --port 0 --token "$TOKEN" --height 256 > "$WORK/serve.log" 2>&1 &
  PID=$!
  for _ in $(seq 600); do
    PORT=$(sed -n 's|.*open http://127.0.0.1:\([0-9]*\)/.*|\1|p' "$WORK/serve.log")
    [ -n "$PORT" ] && break
    sleep 0.1
  done
  [ -n "$PORT" ] || { cat "$WORK/serve.log"; exit 1; }
  URL=http://127.0.0.1:$PORT
}
api() { curl -s -H "X-Instainpaint-Token: $TOKEN" "$@"; }
rss_mb() { awk -v k="$1:" '$1 == k { printf "%.0f", $2 / 1024 }' "/proc/$PID/status"; }
start_edit() { api -o /dev/null -w "%{http_code}" -F view=$VIEW -F "mask=@$MASK" -F "refine=${1:-0}" "$URL/api/edit"; }
job_state() { api "$URL/api/job" | python3 -c 'import json, sys; j = json.load(sys.stdin); print(j["state"], j.get("id", ""))'; }
wait_job() { while [ "$(job_state | cut -d' ' -f1)" = running ]; do sleep 0.2; done; job_state; }

start_server
api -o /dev/null "$URL/api/info"
echo "server: pid $PID, port $PORT, idle RSS $(rss_mb VmRSS) MB"

echo "== 1. wrk, $CONNECTIONS connections, $SECONDS_ s each, while an edit runs"
for path in /api/info /api/views/3/image; do
  echo "edit with 300 refinement steps started: HTTP $(start_edit 300)"
  wrk -t 2 -c "$CONNECTIONS" -d "${SECONDS_}s" --latency -H "X-Instainpaint-Token: $TOKEN" "$URL$path" |
    grep -E "Requests/sec|Latency|50%|90%|99%|Non-2xx|Socket errors|requests in"
  echo "the edit after the load: $(wait_job)"
done

echo "== 2. slow clients: 8 requests sent one byte a second"
python3 - "$PORT" "$TOKEN" <<'PY'
import socket, sys, threading, time, urllib.request
port, token = int(sys.argv[1]), sys.argv[2]
request = f"GET /api/info HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Instainpaint-Token: {token}\r\n\r\n".encode()
dropped = []
def slow():
    s = socket.create_connection(("127.0.0.1", port))
    start = time.time()
    try:
        for b in request:
            s.send(bytes([b]))
            time.sleep(1)
        s.recv(1)
    except OSError:
        pass
    dropped.append(time.time() - start)
threads = [threading.Thread(target=slow) for _ in range(8)]
for t in threads: t.start()
time.sleep(2)
times = []
for _ in range(5):
    t = time.time()
    r = urllib.request.urlopen(urllib.request.Request(f"http://127.0.0.1:{port}/api/info", headers={"X-Instainpaint-Token": token}))
    r.read()
    times.append(time.time() - t)
    time.sleep(0.5)
for t in threads: t.join(timeout=120)
print(f"/api/info meanwhile: {max(times) * 1000:.0f} ms at most; slow clients dropped after "
      f"{min(dropped):.0f}-{max(dropped):.0f} s (of the {len(request)} s they would need)")
PY

echo "== 3. a client that disconnects in the middle of an upload"
before=$(find "$WORK/out" -type f | wc -l)
python3 - "$PORT" "$TOKEN" "$MASK" <<'PY'
import socket, sys
port, token, mask = int(sys.argv[1]), sys.argv[2], open(sys.argv[3], "rb").read()
boundary = "b0undary"
body = (f"--{boundary}\r\nContent-Disposition: form-data; name=\"view\"\r\n\r\nIMG_2707\r\n"
        f"--{boundary}\r\nContent-Disposition: form-data; name=\"mask\"; filename=\"m.png\"\r\n"
        f"Content-Type: image/png\r\n\r\n").encode() + mask + f"\r\n--{boundary}--\r\n".encode()
head = (f"POST /api/edit HTTP/1.1\r\nHost: 127.0.0.1\r\nX-Instainpaint-Token: {token}\r\n"
        f"Content-Type: multipart/form-data; boundary={boundary}\r\nContent-Length: {len(body)}\r\n\r\n").encode()
s = socket.create_connection(("127.0.0.1", port))
s.sendall(head + body[: len(body) // 2])
s.close()
PY
sleep 2
after=$(find "$WORK/out" -type f | wc -l)
echo "files under out/ before $before, after $after; job: $(job_state); /api/info: HTTP $(api -o /dev/null -w '%{http_code}' "$URL/api/info")"

echo "== 4. kill -9 during an edit, then a restart"
echo "edit started: HTTP $(start_edit)"
killed=$(job_state | cut -d' ' -f2)
sleep 1.5
kill -9 "$PID"
wait "$PID" 2> /dev/null || true
echo "killed during job $killed; its folder holds: $(cd "$WORK/out/jobs/$killed" && find . -type f | sort | tr '\n' ' ')"
start_server
echo "after the restart: job $killed's gaussians.ply: HTTP $(api -o /dev/null -w '%{http_code}' "$URL/api/jobs/$killed/gaussians.ply"); next edit: HTTP $(start_edit), $(wait_job)"

echo "== 5. a 16000 x 16000 PNG as the reference"
python3 - "$WORK/bomb.png" <<'PY'
import struct, sys, zlib
w = h = 16000
raw = zlib.compress(b"".join(b"\0" + b"\0" * (w * 3) for _ in range(h)), 9)
chunk = lambda t, d: struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d) & 0xffffffff)
open(sys.argv[1], "wb").write(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)) +
                              chunk(b"IDAT", raw) + chunk(b"IEND", b""))
PY
peak_before=$(rss_mb VmHWM)
answer=$(api -w ' HTTP %{http_code}' -F view=$VIEW -F "mask=@$MASK" -F "reference=@$WORK/bomb.png" "$URL/api/edit")
echo "bomb of $(du -k "$WORK/bomb.png" | cut -f1) KB: $answer; peak RSS $peak_before -> $(rss_mb VmHWM) MB"
