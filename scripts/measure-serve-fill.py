#!/usr/bin/env python3
"""Times the page's Fill (POST /api/fill with a box, as the page's box tool sends it) on a splat
file served by `instainpaint serve --ply`, without a browser: the time from the POST to the job's
end, for each run, and the server's stage table of the last run (the 2D inpainter's share is its
own row). Only Python's standard library.

Example:
  scripts/measure-serve-fill.py --bin build/instainpaint --ply room/scene.ply --box 0,0.4,0,0.2,0.25,0.2 --runs 3
"""
import argparse
import json
import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
serve_edit = __import__("measure-serve-edit")
stage_table = __import__("stage-table")


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--bin", required=True)
    parser.add_argument("--ply", required=True, help="the splat file to fill")
    parser.add_argument("--box", required=True, help="cx,cy,cz,sx,sy,sz: the region")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("serve_args", nargs="*", help="more serve options after --")
    args = parser.parse_args()
    out = tempfile.mkdtemp(prefix="ii-serve-fill-")
    command = [args.bin, "serve", "--ply", args.ply, "--port", "0", "--token", serve_edit.TOKEN, "--out", out,
               *args.serve_args]
    server, base = serve_edit.start_server(command, "measure-serve-fill")
    try:
        info = json.loads(serve_edit.request(base, "/api/info")[1])
        print("inpainter:", info.get("inpainter", {}).get("network", info.get("inpainter", {}).get("name")))
        job = None
        for run in range(1, args.runs + 1):
            body, content_type = serve_edit.multipart({"ply": "/api/plys/0", "box": args.box})
            start = time.perf_counter()
            status, answer = serve_edit.request(base, "/api/fill", body, content_type)
            if status != 202:
                sys.exit(f"measure-serve-fill: refused ({status}): {answer.decode(errors='replace')}")
            job = serve_edit.wait_for_job(base, json.loads(answer)["job"])
            if job["state"] != "done":
                sys.exit(f"measure-serve-fill: the fill failed: {job.get('error')}")
            print(f"run {run}: POST to the job's end {time.perf_counter() - start:.3f} s (server {job['seconds']:.3f} s)")
        job = json.loads(serve_edit.request(base, "/api/job")[1])
        print(stage_table.table(*stage_table.stage_rows(job), title=f"server stages of run {args.runs} (ms)"))
    finally:
        server.terminate()
        server.wait(timeout=30)


if __name__ == "__main__":
    main()
