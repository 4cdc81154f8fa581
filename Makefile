# Two targets for a newcomer; both set everything up first (scripts/setup.sh is idempotent).
.PHONY: setup demo test test-fast lint

setup:
	@bash scripts/setup.sh

# The paper's Fig. 2 subject: a 40 mm wholemilk Stanford bunny, 800x800, the default (multiscale) transport, on a
# floor with two lights.
demo: setup
	.venv/bin/convsss render --mesh bunny --material wholemilk --size-mm 40 --floor --width 800 --height 800 \
		--spp 16 -o out/demo/bunny --stats out/demo/bunny.json
	@echo "demo image: $(CURDIR)/out/demo/bunny.png (linear: out/demo/bunny.exr, timings: out/demo/bunny.json)"

# Everything, the editor's page driven in Chromium among it (setup installs Debian's chromium when missing).
test:
	@bash scripts/setup.sh --browser
	.venv/bin/python -m pytest -q

# The fast loop: every test but those marked slow (renders over a second, subprocesses, Ctrl-C, the battery's matrix,
# the notebook); `make test` (CI) runs them all.
test-fast: setup
	.venv/bin/python -m pytest -q -m "not slow" -n 2

lint: setup
	.venv/bin/ruff check src tests
