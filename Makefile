# One command each, on a fresh machine: `make demo` (set up + reproduce the paper example),
# `make test` (set up with the test extras + run the test suite).
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
# torch comes from constraints.txt: 2.13.0 is the only CPU build here; unpinned pulls CUDA.
# --no-compile: the installed modules are byte-compiled when first imported, not all at install
# (torch, Ray and MuJoCo ship thousands that nothing here imports: 42 -> 23 s for the extras);
# that needs Python allowed to write its bytecode, whatever the shell says
PIP := $(BIN)/python -m pip install --disable-pip-version-check -q --no-compile -c constraints.txt
export PYTHONDONTWRITEBYTECODE =
OUT ?= out

.PHONY: demo test check fuzz bench install clean

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

$(VENV)/.installed: pyproject.toml constraints.txt | $(BIN)/python
	$(PIP) torch==2.13.0
	$(PIP) -e ".[all]"
	touch $@

# one resolve for a fresh venv: the test extras with the rest, not after it
$(VENV)/.installed-test: pyproject.toml constraints.txt | $(BIN)/python
	$(PIP) torch==2.13.0
	$(PIP) -e ".[all,test]"
	touch $(VENV)/.installed $@

install: $(VENV)/.installed

demo: $(VENV)/.installed
	$(BIN)/esp-gym paper --out $(OUT)/paper

# the environment's configurations compiled first, in up to two processes (esp-gym compile: each compiles
# once instead of in whichever test worker meets it first); then two processes for most of the
# suite, then the clock-sensitive modules alone (tests/conftest.py); both parts always run, and the
# target fails if either did
# OpenBLAS's Haswell kernels on every x86-64 machine: the documented comparisons (docs/compare) were
# written with them (the baselines' products; the policies run in float64 loops of their own,
# agents/mlp.py), and an AVX-512 CPU's own kernels round differently, which a chaotic hard episode
# grows into a different return (tests/test_zoo.py, tests/test_team_env.py rerun them to 1e-6)
test: export OPENBLAS_CORETYPE = Haswell
test: $(VENV)/.installed-test
	$(BIN)/esp-gym compile --no-progress
	$(BIN)/python -m pytest -n 2 --dist loadfile -m "not serial"; parallel=$$?; \
	$(BIN)/python -m pytest -p no:xdist -m serial; serial=$$?; \
	test $$parallel -eq 0 -a $$serial -eq 0

# the quick inner loop: the suite without the scripts' end-to-end runs (slow) and the clock-sensitive
# modules (serial); under a minute with a warm kernel cache
check: export OPENBLAS_CORETYPE = Haswell
check: $(VENV)/.installed-test
	$(BIN)/python -m pytest -n 2 --dist loadfile -m "not serial and not slow" -q

# the property and fuzz tests with fresh examples (make test draws the same ones every run)
fuzz: $(VENV)/.installed-test
	HYPOTHESIS_PROFILE=explore $(BIN)/python -m pytest -n 2 --dist loadfile tests/test_properties.py \
		tests/test_params.py tests/test_fuzz_scenes.py tests/test_fuzz_cli.py tests/test_arguments.py

bench: $(VENV)/.installed
	$(BIN)/python -m benchmarks.step_cost

clean:
	rm -rf $(VENV) $(OUT) .pytest_cache
	find esp_gym tests agents benchmarks -name __pycache__ -prune -exec rm -rf {} +
