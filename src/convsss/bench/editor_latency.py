"""``convsss edit``'s latency over HTTP, as the page sees it (issue 61): from the command's start until the page's
first image; per edit type (colour, mean free path, preset, eta), from the request until the POST's answer (the
edit's first pass published, its version in the state) and until ``/image.png`` served it. Medians of 3 edits, each
after 1 s idle (passes refine meanwhile unless ``max_spp`` is 0). A 40 mm skin1 bunny (the quick scene), 512², 1 spp.

    python -m convsss.bench.editor_latency [MAX_SPP]
"""

import http.client
import json
import re
import signal
import statistics
import subprocess
import sys
import time

#: The edits, three of each type.
EDITS = {"colour": [{"color": [0.5, 0.3, 0.2]}, {"color": [0.6, 0.35, 0.2]}, {"color": [0.55, 0.3, 0.25]}],
         "mfp": [{"mfp_mm": [1.0, 0.6, 0.3]}, {"mfp_mm": [1.2, 0.5, 0.25]}, {"mfp_mm": [0.9, 0.6, 0.3]}],
         "preset": [{"preset": "wholemilk"}, {"preset": "ketchup"}, {"preset": "skin1"}],
         "eta": [{"eta": 1.4}, {"eta": 1.33}, {"eta": 1.5}]}


def editor_latency(max_spp=256, width=512):
    """Prints and returns ``{"first_image": s, edit type: (answered s, served s)}`` (medians)."""
    start = time.perf_counter()
    proc = subprocess.Popen([sys.executable, "-m", "convsss", "edit", "--mesh", "bunny", "--material", "skin1",
                             "--size-mm", "40", "--width", str(width), "--height", str(width), "--port", "0",
                             "--no-open", "--max-spp", str(max_spp)],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
    try:
        port = int(re.search(r"http://127\.0\.0\.1:(\d+)/", proc.stdout.readline()).group(1))
        connection = http.client.HTTPConnection("127.0.0.1", port, timeout=300)

        def request(method, path, body=None):
            headers = {"Content-Type": "application/json"} if body is not None else {}
            connection.request(method, path, None if body is None else json.dumps(body), headers)
            response = connection.getresponse()
            return response.status, response.read()

        request("GET", "/")
        request("GET", "/api/state")
        request("GET", "/image.png")
        out = {"first_image": time.perf_counter() - start}
        print(f"max_spp {max_spp}: the page's first image {out['first_image']:.2f} s after the command started")
        for name, changes in EDITS.items():
            answered, served = [], []
            for change in changes:
                time.sleep(1.0)  # idle: passes refine meanwhile
                t = time.perf_counter()
                status, body = request("POST", "/api/update", change)
                assert status == 200, body
                answered.append(time.perf_counter() - t)
                request("GET", f"/image.png?v={json.loads(body)['version']}")
                served.append(time.perf_counter() - t)
            out[name] = statistics.median(answered), statistics.median(served)
            print(f"  {name:7s} answered {out[name][0] * 1000:.0f} ms, image served {out[name][1] * 1000:.0f} ms "
                  "(medians of 3)", flush=True)
        t = time.perf_counter()
        request("GET", "/image.png?v=last&denoised=1")
        out["denoised"] = time.perf_counter() - t
        print(f"  the denoised image served in {out['denoised'] * 1000:.0f} ms")
        return out
    finally:
        proc.send_signal(signal.SIGINT)
        proc.wait(60)


if __name__ == "__main__":
    editor_latency(*(int(a) for a in sys.argv[1:]))
