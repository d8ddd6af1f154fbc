#!/usr/bin/env python3
"""instainpaint models against a server on the loopback address that serves the repository's own
seeded fixture files under the published names, and misbehaves on request: a file whose checksum
differs, a transfer cut halfway, a 404, a stalled server, two downloads of one file at once, a
cache folder that cannot be made, a name not in the catalogue. Then the commands' "auto" choice:
`models get` and the next command uses the cache's networks without a flag.

usage: download_test.py INSTAINPAINT_EXECUTABLE    (ctest: models.Download)
"""
import hashlib
import http.server
import json
import os
import shutil
import subprocess
import sys
import tempfile
import threading
import time
import unittest
import urllib.request
import zipfile

EXE = None
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
FIXTURES = {
    "mobile_sam.pt": os.path.join(ROOT, "tests/segment/fixture/mobile_sam_small.pt"),
    "big-lama.pt": os.path.join(ROOT, "tests/inpaint/fixture/big-lama.pt"),
}
PHOTO = os.path.join(ROOT, "tests/segment/fixture/image.png")
LAMA_CKPT = os.path.join(ROOT, "tests/inpaint/fixture/lama-small/models/best.ckpt")


def md5(path):
    return hashlib.md5(open(path, "rb").read()).hexdigest()


class Files(http.server.BaseHTTPRequestHandler):
    """GET /NAME: the fixture published under NAME, in the mode the test set for it."""
    modes = {}      # name -> "ok" | "cut" (the first answer stops halfway) | "404" | "stall" | "slow"
    requests = []   # (name, Range header) of every request
    lock = threading.Lock()

    def log_message(self, *args):
        pass

    def do_GET(self):
        name = urllib.request.unquote(self.path.lstrip("/"))
        with Files.lock:
            Files.requests.append((name, self.headers.get("Range")))
            mode = Files.modes.get(name, "ok")
            if mode == "cut":
                Files.modes[name] = "ok"  # the next request is answered whole
        if name not in FIXTURES or mode == "404":
            self.send_error(404)
            return
        data = open(FIXTURES[name], "rb").read()
        start = 0
        if self.headers.get("Range", "").startswith("bytes="):
            start = int(self.headers["Range"][6:].split("-")[0])
            if start >= len(data):
                self.send_error(416)
                return
            self.send_response(206)
            self.send_header("Content-Range", f"bytes {start}-{len(data) - 1}/{len(data)}")
        else:
            self.send_response(200)
        self.send_header("Content-Length", str(len(data) - start))
        self.end_headers()
        body = data[start:]
        if mode == "stall":
            self.wfile.write(body[:1000])
            self.wfile.flush()
            time.sleep(8)  # longer than the client's --timeout
            return
        if mode == "cut":
            self.wfile.write(body[: len(body) // 2])
            self.wfile.flush()
            self.close_connection = True
            return
        if mode == "slow":  # about 2 s for the whole file: long enough for a second client to wait
            step = max(1, len(body) // 20)
            for i in range(0, len(body), step):
                self.wfile.write(body[i : i + step])
                self.wfile.flush()
                time.sleep(0.1)
            return
        self.wfile.write(body)


class ModelsCommand(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        # The authors' archive of big-lama, made of the fixture's best.ckpt as theirs holds it.
        cls.archive_dir = tempfile.mkdtemp(prefix="ii-models-archive-")
        FIXTURES["big-lama.zip"] = os.path.join(cls.archive_dir, "big-lama.zip")
        with zipfile.ZipFile(FIXTURES["big-lama.zip"], "w") as z:
            z.writestr("big-lama/config.yaml", "generator: ffc_resnet\n")
            z.write(LAMA_CKPT, "big-lama/models/best.ckpt")
        cls.server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), Files)
        cls.mirror = f"http://127.0.0.1:{cls.server.server_address[1]}"
        threading.Thread(target=cls.server.serve_forever, daemon=True).start()

    @classmethod
    def tearDownClass(cls):
        cls.server.shutdown()
        shutil.rmtree(cls.archive_dir, ignore_errors=True)

    def setUp(self):
        Files.modes = {}
        Files.requests = []
        self.work = tempfile.mkdtemp(prefix="ii-models-test-")
        self.cache = os.path.join(self.work, "cache")
        # The fixtures under the published names, pinned to their own MD5s (the built-in
        # catalogue pins the published files, which this machine cannot reach).
        self.catalogue = os.path.join(self.work, "catalogue.json")
        with open(self.catalogue, "w") as f:
            json.dump([
                {"name": "mobile-sam", "role": "segmenter", "file": "mobile_sam.pt", "urls": [self.mirror + "/mobile_sam.pt"],
                 "md5": md5(FIXTURES["mobile_sam.pt"]), "checksum_source": "the test"},
                {"name": "big-lama", "role": "inpainter", "file": "big-lama.pt", "urls": [self.mirror + "/big-lama.pt"],
                 "md5": md5(FIXTURES["big-lama.pt"]), "checksum_source": "the test"},
                {"name": "big-lama-authors", "role": "inpainter", "file": "big-lama-best.ckpt",
                 "urls": [self.mirror + "/big-lama.zip"], "archive_member": "models/best.ckpt"},
            ], f)

    def tearDown(self):
        shutil.rmtree(self.work, ignore_errors=True)

    def run_cli(self, *args, catalogue=True, cache=None, timeout=60, check=None):
        env = dict(os.environ, INSTAINPAINT_MODELS_DIR=cache or self.cache)
        env.pop("INSTAINPAINT_MODELS_MIRROR", None)
        env.pop("INSTAINPAINT_SEGMENTER", None)
        env.pop("INSTAINPAINT_INPAINTER", None)
        env.pop("INSTAINPAINT_MODELS_CATALOGUE", None)
        if catalogue:
            env["INSTAINPAINT_MODELS_CATALOGUE"] = self.catalogue
        p = subprocess.run([EXE, *args], env=env, capture_output=True, text=True, timeout=timeout)
        if check is not None:
            self.assertEqual(p.returncode, check, p.stdout + p.stderr)
        return p

    def cache_files(self):
        return sorted(f for f in os.listdir(self.cache) if not f.endswith(".lock")) if os.path.isdir(self.cache) else []

    def test_get_checks_and_records_the_file(self):
        self.run_cli("models", "get", "mobile-sam", check=0)
        path = self.run_cli("models", "path", "mobile-sam", check=0).stdout.strip()
        self.assertEqual(path, os.path.join(self.cache, "mobile_sam.pt"))
        self.assertEqual(md5(path), md5(FIXTURES["mobile_sam.pt"]))
        record = json.load(open(path + ".record.json"))
        self.assertEqual(record["sha256"], hashlib.sha256(open(path, "rb").read()).hexdigest())
        self.assertTrue(record["pinned"])
        listed = json.loads(self.run_cli("models", "list", "--json", check=0).stdout)
        states = {n["name"]: n["state"] for n in listed["networks"]}
        self.assertEqual(states["mobile-sam"], "verified")
        self.assertEqual(states["big-lama"], "absent")
        self.assertEqual(listed["auto"]["segmenter"], "mobile-sam")
        self.assertIsNone(listed["auto"]["inpainter"])
        self.assertIn("mobile-sam: verified", self.run_cli("models", "verify", check=0).stdout)
        # a second get does not download again
        before = len(Files.requests)
        self.assertIn("already in the cache", self.run_cli("models", "get", "mobile-sam", check=0).stdout)
        self.assertEqual(len(Files.requests), before)

    def test_a_checksum_that_differs_is_refused_and_deleted(self):
        # The built-in catalogue pins the published mobile_sam.pt; the mirror serves the fixture.
        p = self.run_cli("models", "get", "mobile-sam", "--mirror", self.mirror, catalogue=False, check=1)
        self.assertIn(md5(FIXTURES["mobile_sam.pt"]), p.stderr)  # what arrived
        self.assertIn("f3c0d8cda613564d499310dab6c812cd", p.stderr)  # what IOPaint publishes
        self.assertIn("deleted", p.stderr)
        self.assertEqual(self.cache_files(), [])

    def test_a_cut_transfer_resumes(self):
        Files.modes["mobile_sam.pt"] = "cut"
        p = self.run_cli("models", "get", "mobile-sam", check=1)
        self.assertIn("the same command resumes it", p.stderr)
        self.assertEqual(self.cache_files(), ["mobile_sam.pt.part"])
        half = os.path.getsize(os.path.join(self.cache, "mobile_sam.pt.part"))
        size = os.path.getsize(FIXTURES["mobile_sam.pt"])
        self.assertEqual(half, size // 2)
        p = self.run_cli("models", "get", "mobile-sam", check=0)
        self.assertEqual(Files.requests[-1], ("mobile_sam.pt", f"bytes={half}-"))
        self.assertIn("resumed", p.stderr)
        self.assertEqual(md5(os.path.join(self.cache, "mobile_sam.pt")), md5(FIXTURES["mobile_sam.pt"]))
        self.assertEqual(self.cache_files(), ["mobile_sam.pt", "mobile_sam.pt.record.json"])

    def test_a_partial_file_that_is_whole_already_is_checked_and_kept(self):
        os.makedirs(self.cache)
        shutil.copy(FIXTURES["mobile_sam.pt"], os.path.join(self.cache, "mobile_sam.pt.part"))
        self.run_cli("models", "get", "mobile-sam", check=0)
        self.assertEqual(Files.requests[-1], ("mobile_sam.pt", f"bytes={os.path.getsize(FIXTURES['mobile_sam.pt'])}-"))
        self.assertEqual(self.cache_files(), ["mobile_sam.pt", "mobile_sam.pt.record.json"])

    def test_an_archive_keeps_its_member(self):
        self.run_cli("models", "get", "big-lama-authors", check=0)
        self.assertEqual(Files.requests[-1], ("big-lama.zip", None))
        kept = os.path.join(self.cache, "big-lama-best.ckpt")
        self.assertEqual(md5(kept), md5(LAMA_CKPT))  # the member, the archive not kept
        self.assertEqual(self.cache_files(), ["big-lama-best.ckpt", "big-lama-best.ckpt.record.json"])
        record = json.load(open(kept + ".record.json"))
        self.assertFalse(record["pinned"])
        self.assertTrue(record["origin"].endswith("(its big-lama/models/best.ckpt)"))
        self.assertIn("unchanged since its first get", self.run_cli("models", "verify", check=0).stdout)
        # The only inpainter in the cache: what auto takes.
        self.assertEqual(json.loads(self.run_cli("models", "list", "--json", check=0).stdout)["auto"]["inpainter"],
                         "big-lama-authors")
        # Imported by hand: the archive, or the member itself.
        self.assertIn("removed", self.run_cli("models", "remove", "big-lama-authors", check=0).stdout)
        self.run_cli("models", "import", FIXTURES["big-lama.zip"], "--as", "big-lama-authors", check=0)
        self.assertEqual(md5(kept), md5(LAMA_CKPT))
        self.run_cli("models", "remove", "big-lama-authors", check=0)
        self.run_cli("models", "import", LAMA_CKPT, "--as", "big-lama-authors", check=0)
        self.assertEqual(md5(kept), md5(LAMA_CKPT))
        # An archive without the member is refused, nothing kept.
        self.run_cli("models", "remove", "big-lama-authors", check=0)
        wrong = os.path.join(self.work, "big-lama.zip")
        with zipfile.ZipFile(wrong, "w") as z:
            z.writestr("big-lama/config.yaml", "x")
        published = FIXTURES["big-lama.zip"]
        FIXTURES["big-lama.zip"] = wrong
        try:
            p = self.run_cli("models", "get", "big-lama-authors", check=1)
        finally:
            FIXTURES["big-lama.zip"] = published
        self.assertIn("holds no models/best.ckpt; deleted", p.stderr)
        self.assertEqual(self.cache_files(), [])

    def test_a_404_is_one_clear_error(self):
        Files.modes["mobile_sam.pt"] = "404"
        p = self.run_cli("models", "get", "mobile-sam", check=1)
        self.assertEqual(p.stderr.strip().splitlines()[-1],
                         f"error: mobile-sam: the download failed: {self.mirror}/mobile_sam.pt: HTTP 404")
        self.assertEqual(self.cache_files(), [])

    def test_a_stalled_server_times_out(self):
        Files.modes["mobile_sam.pt"] = "stall"
        start = time.monotonic()
        p = self.run_cli("models", "get", "mobile-sam", "--timeout", "2", check=1, timeout=30)
        self.assertLess(time.monotonic() - start, 7)
        self.assertIn("nothing arrived for 2 s", p.stderr)
        self.assertNotIn("mobile_sam.pt", self.cache_files())

    def test_two_gets_at_once_download_once(self):
        Files.modes["mobile_sam.pt"] = "slow"
        env_args = ("models", "get", "mobile-sam")
        results = []
        threads = [threading.Thread(target=lambda: results.append(self.run_cli(*env_args))) for _ in range(2)]
        final = os.path.join(self.cache, "mobile_sam.pt")
        size = os.path.getsize(FIXTURES["mobile_sam.pt"])
        for t in threads:
            t.start()
            time.sleep(0.3)
        while any(t.is_alive() for t in threads):  # never a partial file under the final name
            if os.path.exists(final):
                self.assertEqual(os.path.getsize(final), size)
            time.sleep(0.02)
        for p in results:
            self.assertEqual(p.returncode, 0, p.stderr)
        self.assertEqual(sum("waiting for it" in p.stderr for p in results), 1)
        self.assertEqual(len([r for r in Files.requests if r[0] == "mobile_sam.pt"]), 1)
        self.assertEqual(md5(final), md5(FIXTURES["mobile_sam.pt"]))

    def test_a_cache_folder_that_cannot_be_made(self):
        blocker = os.path.join(self.work, "a-file")
        open(blocker, "w").close()
        p = self.run_cli("models", "get", "mobile-sam", cache=os.path.join(blocker, "models"), check=1)
        self.assertIn("the models' folder cannot be made", p.stderr)
        self.assertIn("INSTAINPAINT_MODELS_DIR", p.stderr)

    def test_a_name_not_in_the_catalogue(self):
        p = self.run_cli("models", "get", "sam3", catalogue=False, check=1)
        self.assertEqual(p.stderr.strip(), "error: 'sam3' is not a network of the catalogue: "
                         "instainpaint, mobile-sam, sam-vit-b, sam-vit-l, sam-vit-h, big-lama, big-lama-authors")

    def test_import_checks_like_a_download(self):
        p = self.run_cli("models", "import", FIXTURES["big-lama.pt"], "--as", "big-lama", catalogue=False, check=1)
        self.assertIn("e3aa4aaa15225a33ec84f9f4bc47e500", p.stderr)
        self.assertIn(md5(FIXTURES["big-lama.pt"]), p.stderr)
        self.assertEqual(self.cache_files(), [])
        self.run_cli("models", "import", FIXTURES["big-lama.pt"], "--as", "big-lama", check=0)
        self.assertIn("big-lama: verified", self.run_cli("models", "verify", "big-lama", check=0).stdout)
        # A changed file is no longer used, and verify says what differs.
        with open(os.path.join(self.cache, "big-lama.pt"), "r+b") as f:
            f.seek(100)
            f.write(b"\xff")
        listed = json.loads(self.run_cli("models", "list", "--json", check=0).stdout)
        self.assertIsNone(listed["auto"]["inpainter"])
        p = self.run_cli("models", "verify", "big-lama", check=1)
        self.assertIn("is not the published file", p.stderr)
        self.assertIn("removed", self.run_cli("models", "remove", "big-lama", check=0).stdout)
        self.assertEqual(self.cache_files(), [])

    def test_the_commands_use_the_cache_without_a_flag(self):
        out = os.path.join(self.work, "mask.png")
        # Nothing cached: segment needs a network and says the command that brings one.
        p = self.run_cli("segment", "--image", PHOTO, "--click", "20,20", "--out", out, check=1)
        self.assertIn("instainpaint models get mobile-sam", p.stderr)
        self.run_cli("models", "get", "mobile-sam", "big-lama", check=0)
        p = self.run_cli("segment", "--image", PHOTO, "--click", "20,20", "--out", out, "--json", check=0)
        summary = json.loads(p.stdout)
        self.assertEqual(summary["file"], os.path.join(self.cache, "mobile_sam.pt"))
        self.assertEqual(summary["from"], "the cache")
        p = self.run_cli("inpaint", "--image", PHOTO, "--mask", out, "--out", os.path.join(self.work, "painted.png"),
                         "--json", check=0)
        inpainter = json.loads(p.stdout)["inpainter"]
        self.assertEqual((inpainter["name"], inpainter["from"]), ("lama", "the cache"))
        p = self.run_cli("inpaint", "--inpainter", "ns", "--image", PHOTO, "--mask", out, "--out",
                         os.path.join(self.work, "ns.png"), "--json", check=0)
        self.assertEqual(json.loads(p.stdout)["inpainter"]["name"], "ns")

    def test_serve_after_get_runs_the_cache_networks_and_encodes_every_view_behind(self):
        statue = os.path.join(os.environ.get("INSTAINPAINT_SHARED", os.path.join(ROOT, "..", "shared")), "data", "statue")
        if not os.path.isfile(os.path.join(statue, "PROVENANCE.md")):
            self.skipTest(f"shared data missing: {statue}")
        self.run_cli("models", "get", "mobile-sam", "big-lama", check=0)
        # The built-in model's own file stands in for the released checkpoint (a CPU page offers it
        # as a slower Run beside the built-in model's).
        released = os.path.join(ROOT, "models", "default.safetensors")
        entries = json.load(open(self.catalogue))
        entries.append({"name": "instainpaint", "role": "checkpoint", "file": "released-stand-in.safetensors",
                        "urls": [self.mirror + "/released-stand-in.safetensors"], "md5": md5(released)})
        json.dump(entries, open(self.catalogue, "w"))
        self.run_cli("models", "import", released, "--as", "instainpaint", check=0)
        env = dict(os.environ, INSTAINPAINT_MODELS_DIR=self.cache, INSTAINPAINT_MODELS_CATALOGUE=self.catalogue)
        for name in ("INSTAINPAINT_SEGMENTER", "INSTAINPAINT_INPAINTER"):
            env.pop(name, None)
        server = subprocess.Popen([EXE, "serve", "--scene", statue, "--height", "64", "--port", "0", "--no-token",
                                   "--out", os.path.join(self.work, "serve")], env=env, stdout=subprocess.PIPE,
                                  stderr=subprocess.DEVNULL, text=True)
        try:
            line = server.stdout.readline()
            self.assertIn("open http://127.0.0.1:", line)
            base = line.split("open ")[1].split(" ")[0].rstrip("/")
            deadline = time.monotonic() + 120
            while True:
                info = json.load(urllib.request.urlopen(base + "/api/info", timeout=10))
                views = len(info["scene"]["views"])
                if info["segmenter"]["views_encoded"] == views or time.monotonic() > deadline:
                    break
                time.sleep(0.2)
            networks = info["networks"]
            self.assertEqual((networks["segmenter"]["file"], networks["segmenter"]["from"]), ("mobile_sam.pt", "the cache"))
            self.assertEqual((networks["inpainter"]["file"], networks["inpainter"]["from"]), ("big-lama.pt", "the cache"))
            self.assertEqual(networks["model"], {"file": "<embedded default model>", "from": "built in"})  # on a CPU
            self.assertEqual(networks["released"]["file"], "released-stand-in.safetensors")
            self.assertEqual(info["segmenter"]["views_encoded"], views)  # all of them, behind the page
            # A click after that only decodes.
            boundary = "xyz"
            body = "".join(f'--{boundary}\r\nContent-Disposition: form-data; name="{k}"\r\n\r\n{v}\r\n'
                           for k, v in (("view", "3"), ("clicks", "100,80"))) + f"--{boundary}--\r\n"
            request = urllib.request.Request(base + "/api/select", data=body.encode(), method="POST",
                                             headers={"Content-Type": f"multipart/form-data; boundary={boundary}"})
            answer = json.load(urllib.request.urlopen(request, timeout=30))
            self.assertEqual(answer["how"], "segmenter")
            self.assertLess(answer["ms"]["encode"], 5)
            # Run with the released checkpoint: the same edit on the second model.
            view = info["scene"]["views"][3]
            mask = urllib.request.urlopen(base + view["mask"], timeout=30).read()
            parts = [(k, None, v.encode()) for k, v in (("view", view["name"]), ("mode", "remove"), ("refine", "0"),
                                                         ("model", "released"))] + [("mask", "mask.png", mask)]
            body = b"".join(f'--{boundary}\r\nContent-Disposition: form-data; name="{k}"'.encode() +
                            (f'; filename="{f}"\r\nContent-Type: image/png'.encode() if f else b"") +
                            b"\r\n\r\n" + v + b"\r\n" for k, f, v in parts) + f"--{boundary}--\r\n".encode()
            request = urllib.request.Request(base + "/api/edit", data=body, method="POST",
                                             headers={"Content-Type": f"multipart/form-data; boundary={boundary}"})
            job = json.load(urllib.request.urlopen(request, timeout=30))["job"]
            while True:
                state = json.load(urllib.request.urlopen(f"{base}/api/job?wait={job}", timeout=120))
                if state["id"] == job and state["state"] != "running":
                    break
            self.assertEqual(state["state"], "done", state.get("error"))
            self.assertEqual(state["result"]["model"], "released-stand-in.safetensors")
        finally:
            server.terminate()
            server.wait(timeout=30)


if __name__ == "__main__":
    EXE = os.path.abspath(sys.argv.pop(1))
    unittest.main(verbosity=2)
