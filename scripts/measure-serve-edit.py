#!/usr/bin/env python3
"""Times an edit in `instainpaint serve` the way the page's Run button does it, without a browser.

Starts the server on a scene, waits for its first job (the reconstruction), then for each run:
POST /api/edit with a view's own object mask (multipart, as the page sends its painting),
follow /api/job?wait=<id> as the page does (answered as soon as the job ends), fetch the page's
splat file (the edit's figure ends with its last byte), then the propagated masks, which the
page draws after the splats. Prints the server's time, the time from the POST to the splats'
last byte and its parts, and the server's stage table of the last run (scripts/stage-table.py).
What the page adds after that (decoding the splats and drawing them) is measured by the
browser test (tests/web/browser/edit.test.mjs: "splats" part). Only Python's standard
library: it runs on the lent GPU machines too.

Example:
  scripts/measure-serve-edit.py --bin build/instainpaint --scene ../shared/data/statue --runs 3
  scripts/measure-serve-edit.py --bin build-gpu/instainpaint --scene .device/shared/data/statue --device cuda
"""
import argparse
import json
import os
import re
import subprocess
import sys
import tempfile
import time
import urllib.request
import uuid

TOKEN = "measure"


def request(base, path, body=None, content_type=None):
    req = urllib.request.Request(base + path, data=body, headers={"X-Instainpaint-Token": TOKEN})
    if content_type:
        req.add_header("Content-Type", content_type)
    try:
        with urllib.request.urlopen(req, timeout=600) as answer:
            return answer.status, answer.read()
    except urllib.error.HTTPError as error:
        return error.code, error.read()


def multipart(fields):
    """fields: name -> str, or name -> (filename, bytes). Returns (body, content type)."""
    boundary = uuid.uuid4().hex
    parts = []
    for name, value in fields.items():
        if isinstance(value, tuple):
            filename, data = value
            head = f'Content-Disposition: form-data; name="{name}"; filename="{filename}"\r\nContent-Type: image/png\r\n\r\n'
        else:
            head, data = f'Content-Disposition: form-data; name="{name}"\r\n\r\n', value.encode()
        parts.append(f"--{boundary}\r\n{head}".encode() + data + b"\r\n")
    return b"".join(parts) + f"--{boundary}--\r\n".encode(), f"multipart/form-data; boundary={boundary}"


def start_server(command, script):
    """Starts `instainpaint serve` (`command`, with --port 0) and returns (process, base address)."""
    server = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    for line in server.stdout:
        found = re.search(r"open (http://[0-9.:]+)/", line)
        if found:
            return server, found.group(1)
    sys.exit(f"{script}: the server did not start: {' '.join(command)}")


def wait_for_job(base, job_id=None):
    while True:
        path = "/api/job" if job_id is None else f"/api/job?wait={job_id}"
        job = json.loads(request(base, path)[1])
        if job.get("state") != "running" and (job_id is None or job.get("id") == job_id):
            return job
        if job_id is None:
            time.sleep(0.1)


def time_clicks(base, views, count, opened):
    """Waits until the segmenter has encoded every view behind the page, then clicks the middle of
    `count` views (their masks' centre where they have one) and prints each answer's time."""
    while True:
        info = json.loads(request(base, "/api/info")[1])
        if not info.get("segmenter"):
            sys.exit("measure-serve-edit: --clicks needs a segmenter (instainpaint models get mobile-sam)")
        if info["segmenter"]["views_encoded"] == len(views):
            break
        time.sleep(0.2)
    print(f"every view's photo ({len(views)}) encoded behind the page {time.perf_counter() - opened:.1f} s after it was started")
    for i in range(count):
        index = i * len(views) // count
        v = views[index]
        body, content_type = multipart({"view": str(index), "clicks": f"{v['width'] // 2},{v['height'] // 2}"})
        start = time.perf_counter()
        status, answer = request(base, "/api/select", body, content_type)
        seconds = time.perf_counter() - start
        a = json.loads(answer)
        if status != 200:
            sys.exit(f"measure-serve-edit: the click was refused ({status}): {a}")
        print(f"click on view {index}: {1000 * seconds:.0f} ms to the answer (server: encode {a['ms']['encode']:.1f} ms, "
              f"decode {a['ms']['decode']:.1f} ms), {a['pixels']} pixels")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0], epilog=__doc__.split("Example:")[1],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--bin", required=True, help="the instainpaint program")
    parser.add_argument("--scene", required=True, help="a scene with object masks (the statue has one per view)")
    parser.add_argument("--view", type=int, help="index of the view to edit (default: the middle one)")
    parser.add_argument("--runs", type=int, default=3, help="edits to time (the first includes warm-up)")
    parser.add_argument("--refine", default="0", help="the page's refine setting (default 0: feed-forward)")
    parser.add_argument("--clicks", type=int, default=0,
                        help="with a segmenter (serve's auto: the cache's): wait until every view's photo is encoded "
                             "behind the page, then time this many clicks, one on each of as many views, before the edits")
    parser.add_argument("--stages", metavar="FILE", help="also write the last run's job JSON (its stages) here")
    parser.add_argument("--pause", type=float, default=2.0,
                        help="seconds between the first job and the first edit, as a person marking the region "
                             "(default 2; the server prepares the photos' features meanwhile)")
    parser.add_argument("serve_args", nargs="*", help="more serve options after --, e.g. -- --device cuda --height 512")
    args, extra = parser.parse_known_args()
    out = tempfile.mkdtemp(prefix="ii-serve-edit-")
    command = [args.bin, "serve", "--scene", args.scene, "--port", "0", "--token", TOKEN, "--out", out,
               *args.serve_args, *extra]
    opened = time.perf_counter()
    server, base = start_server(command, "measure-serve-edit")
    try:
        info = json.loads(request(base, "/api/info")[1])
        model = info.get("model") or {}
        print(f"server {base}, model {model.get('checkpoint')} ({model.get('config', {}).get('preset')})")
        networks = info.get("networks", {})
        print("networks: " + ", ".join(f"{k} {v.get('network', v.get('file', v.get('instead')))} ({v.get('from', 'absent')})"
                                       for k, v in networks.items() if isinstance(v, dict)))
        first = wait_for_job(base)
        print(f"first job ({first.get('kind', first.get('stage'))}): {first.get('state')} in {first.get('seconds', 0):.2f} s")
        views = info["scene"]["views"]
        if args.clicks:
            time_clicks(base, views, args.clicks, opened)
        time.sleep(args.pause)
        index = args.view if args.view is not None else len(views) // 2
        status, mask = request(base, f"/api/views/{index}/mask")
        if status != 200:
            sys.exit(f"measure-serve-edit: view {index} has no mask ({status})")
        for run in range(1, args.runs + 1):
            body, content_type = multipart({"view": views[index]["name"], "mask": ("mask.png", mask),
                                            "mode": "remove", "refine": args.refine})
            clicked = time.perf_counter()
            status, answer = request(base, "/api/edit", body, content_type)
            if status != 202:
                sys.exit(f"measure-serve-edit: the edit was refused ({status}): {answer.decode(errors='replace')}")
            job = wait_for_job(base, json.loads(answer)["job"])
            seen = time.perf_counter()
            if job["state"] != "done":
                sys.exit(f"measure-serve-edit: the edit failed: {job.get('error')}")
            status, splats = request(base, job["result"]["splats"])
            done = time.perf_counter()
            for url in job["result"].get("masks", {}).values():
                request(base, url)
            masks = time.perf_counter()
            request(base, job["result"]["spz"])  # the download: the next run starts once it is written
            print(f"run {run}: POST to the splats' last byte {done - clicked:.3f} s (server {job['seconds']:.3f} s; "
                  f"job seen done {1000 * (seen - clicked):.0f} ms, splats {1000 * (done - seen):.0f} ms for "
                  f"{len(splats) / 1e6:.1f} MB; {job['result'].get('gaussians')} Gaussians); then the masks "
                  f"{1000 * (masks - done):.0f} ms")
        job = json.loads(request(base, "/api/job")[1])  # with the stages of the files written behind
        sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
        stage_table = __import__("stage-table")
        print(stage_table.table(*stage_table.stage_rows(job), title=f"server stages of run {args.runs} (ms)"))
        if args.stages:
            with open(args.stages, "w", encoding="utf-8") as f:
                json.dump(job, f, indent=2)
    finally:
        server.terminate()
        server.wait(timeout=30)


if __name__ == "__main__":
    main()
