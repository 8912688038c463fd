# pedicle_drilling: the two commands of the README (`make run`, `make test`) and helpers.
# Every target installs the missing Debian packages first, then builds with catkin in Release.
SHELL := /bin/bash
# Debian's ROS Python modules are only visible to /usr/bin/python3: put /usr/bin first so that
# a pyenv (or any other) python3 on PATH cannot break catkin, rostest or our scripts.
export PATH := /usr/bin:/bin:/usr/sbin:/sbin:$(PATH)
export PYTHONNOUSERSITE := 1

WS := $(CURDIR)/catkin_ws
JOBS ?= 2
# ccache (installed by `make deps`) keeps every compilation: a rebuild, and the test that builds
# the install space in a second workspace beside catkin_ws (test_install_space.py), compile only
# what changed. Paths in the checkout are hashed relative to the build directory
# (CCACHE_BASEDIR), the same from both workspaces.
export CCACHE_BASEDIR := $(CURDIR)
CATKIN_MAKE := cd $(WS) && catkin_make -DCMAKE_BUILD_TYPE=Release \
	-DPYTHON_EXECUTABLE=/usr/bin/python3 -DCATKIN_ENABLE_TESTING=ON \
	-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache -j$(JOBS)

.PHONY: all deps build test test-fast run bench docs lint format format-check hooks clean

all: build

deps:
	./scripts/dev/install_deps.sh

build: deps
	./scripts/dev/link_workspace.sh
	$(CATKIN_MAKE)

test: build format-check
	cd $(WS)/build && $(MAKE) -j$(JOBS) tests
	xvfb-run -a -s "-screen 0 1280x1024x24" ./scripts/dev/run_tests.sh

# The developer's loop: the gtest suites, the formatting and the documents' checks, no rostest.
test-fast: build format-check
	cd $(WS)/build && $(MAKE) -j$(JOBS) tests
	TEST_TIER=fast ./scripts/dev/run_tests.sh

run: build
	./scripts/dev/run_main.sh

bench: build
	./scripts/dev/run_bench.sh

# The documents' generated blocks (<!-- generated: NAME -->) from the archived results in
# doc/results/: on a checkout it leaves `git diff` empty. To publish a new `make run`, first
# `scripts/dev/make_docs.py --archive results/` (test_generated_docs.py checks the blocks).
docs: deps
	/usr/bin/python3 scripts/dev/make_docs.py

lint: deps
	./scripts/dev/link_workspace.sh
	catkin_lint -W1 $(WS)/src/pedicle_drilling
	catkin_lint -W1 $(CURDIR)

format: deps
	git ls-files '*.cpp' '*.hpp' '*.h' | xargs clang-format-14 -i

# Fails naming every C++ file clang-format-14 would change (run by `make test`, and by
# test_format.py inside the test run).
format-check: deps
	@bad=$$(for f in $$(git ls-files '*.cpp' '*.hpp' '*.h'); do 	  clang-format-14 --dry-run --Werror "$$f" >/dev/null 2>&1 || echo "$$f"; done); 	if [ -n "$$bad" ]; then echo "not formatted (make format): $$bad"; exit 1; fi; 	echo "format-check: every C++ file is formatted"

# Installs scripts/dev/commit-msg as this clone's commit-msg hook, in the hooks folder git names
# (shared by the clone's worktrees): a copy, so run it again after the hook changes.
hooks:
	@hooks=$$(git rev-parse --git-path hooks) && mkdir -p "$$hooks" && \
	install -m 0755 scripts/dev/commit-msg "$$hooks/commit-msg" && \
	echo "hooks: installed $$hooks/commit-msg"

clean:
	rm -rf $(WS)/build $(WS)/devel $(WS)/src/CMakeLists.txt
