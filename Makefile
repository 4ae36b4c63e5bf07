# geoproc: `make demo` and `make test` do all set-up on a fresh machine.
# Every target is safe under `make -j`.

PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
GEO    := $(VENV)/bin/geoproc
STAMP  := $(VENV)/.setup-stamp
FIXTURES := fixtures/data/.stamp
DEMO   := out/demo
PYTEST_ARGS ?=
# pytest-xdist workers: one per core this process may use, at most 4 (memory);
# TEST_WORKERS=0 runs the tests in one process
TEST_WORKERS ?= $(shell n=$$(nproc 2>/dev/null || echo 2); [ "$$n" -gt 4 ] && n=4; echo $$n)

.PHONY: setup fixtures test test-all demo demo-info demo-geodesic demo-morse-simplify demo-wos-solve demo-perturb demo-denoise demo-summary bench lint clean

setup: $(STAMP)

# Redone only when the package metadata changes.
$(STAMP): pyproject.toml setup.py
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e ".[test]"
	touch $@

fixtures: $(FIXTURES)

$(FIXTURES): fixtures/make_fixtures.py $(wildcard geoproc/*.py geoproc/mesh/*.py) $(STAMP)
	$(PY) fixtures/make_fixtures.py fixtures/data > /dev/null
	touch $@

test: $(STAMP)
	$(PY) -m pytest -q -n $(TEST_WORKERS) $(PYTEST_ARGS)

test-all: $(STAMP)
	$(PY) -m pytest -q -n $(TEST_WORKERS) -m "" $(PYTEST_ARGS)

# ---- demo: every subcommand on the project's own fixtures, into out/demo ----
demo: demo-summary

$(DEMO)/.dir:
	mkdir -p $(DEMO)
	touch $@

demo-info: $(FIXTURES) $(DEMO)/.dir
	$(GEO) info fixtures/data/torus.ply --quiet --report $(DEMO)/info_torus.json --check 'genus==1' > $(DEMO)/info_torus.txt
	$(GEO) info fixtures/data/grid.ply --quiet --json --report $(DEMO)/info_grid.json --check 'boundary_loops==1' > $(DEMO)/info_grid.txt

demo-morse-simplify: $(FIXTURES) $(DEMO)/.dir
	$(GEO) morse-simplify fixtures/data/torus.ply --field x --persistence 0.1 -o $(DEMO)/morse_torus.ply --critical $(DEMO)/morse_torus_critical.json --quiet --report $(DEMO)/morse_torus.json --check 'saddles_after==2'
	$(GEO) morse-simplify fixtures/data/icosphere.ply --field mean-curvature --persistence 0.5 --relative -o $(DEMO)/morse_sphere.ply --diagram $(DEMO)/morse_sphere.png --quiet --report $(DEMO)/morse_sphere.json --check 'minima_after==12' --check 'maxima_after==1'
	$(GEO) morse-simplify fixtures/data/icosphere.ply --field mean-curvature --persistence 0.5 --relative --barycentric -o $(DEMO)/morse_sphere_exact.ply --quiet --report $(DEMO)/morse_sphere_exact.json --check 'vertices_beyond_half_threshold==0' --check 'minima_after==12' --check 'maxima_after==1'

demo-wos-solve: $(FIXTURES) $(DEMO)/.dir
	$(PY) fixtures/wos_fixtures.py $(DEMO)/wos_inputs > /dev/null
	$(GEO) wos-solve $(DEMO)/wos_inputs/wos_glyph_B.json --boundary 'x**3 - 3*x*y**2' --method cv-green --walks 32 --grid 96 --exact --seed 1 -o $(DEMO)/wos_glyph_B.exr --image $(DEMO)/wos_glyph_B.png --error-image $(DEMO)/wos_glyph_B_error.png --quiet --report $(DEMO)/wos_glyph_B.json --check 'rmse<=0.02'
	$(GEO) wos-solve $(DEMO)/wos_inputs/wos_rect_neumann.json --boundary 'y' --neumann '2*y - 1' --method cv-green --walks 32 --grid 48 --kernels 40 --exact --seed 1 -o $(DEMO)/wos_rect_neumann.exr --image $(DEMO)/wos_rect_neumann.png --quiet --report $(DEMO)/wos_rect_neumann.json --check 'rmse<=0.02'
	$(GEO) wos-solve $(DEMO)/wos_inputs/wos_mask.png --boundary '(x - 64)/50' --method cv-green --walks 16 --grid 96 --epsilon 0.01 --exact --seed 1 -o $(DEMO)/wos_mask.exr --image $(DEMO)/wos_mask.png --quiet --report $(DEMO)/wos_mask.json --check 'rmse<=0.02'

demo-geodesic: $(FIXTURES) $(DEMO)/.dir
	$(GEO) geodesic fixtures/data/torus.ply -s 0 -m log-heat --reference exact -o $(DEMO)/geodesic_torus.ply --render $(DEMO)/geodesic_torus.png --quiet --report $(DEMO)/geodesic_torus.json --check 'mean_relative_error<=0.02'
	$(GEO) geodesic fixtures/data/grid.ply -s 0 -s 440 -m heat --reference exact -o $(DEMO)/geodesic_grid.ply --quiet --report $(DEMO)/geodesic_grid.json --check 'mean_relative_error<=0.02'
	$(GEO) geodesic fixtures/data/icosphere.ply -s 0 -m log-ode --time-factor 1e-30 -o $(DEMO)/geodesic_sphere_tiny_t.ply --quiet --report $(DEMO)/geodesic_sphere_tiny_t.json --check 'nonfinite_distance_vertices==0' --check 'log_heat_below_double>=300'

demo-perturb: $(FIXTURES) $(DEMO)/.dir
	$(GEO) perturb fixtures/data/cube.ply --noise 0.3 --seed 1 -o $(DEMO)/perturb_cube.ply --quiet --report $(DEMO)/perturb_cube.json
	$(GEO) perturb fixtures/data/points.ply --noise 0 --outliers 0.2 --outlier-range 0.05 --seed 1 -o $(DEMO)/perturb_points.ply --quiet --report $(DEMO)/perturb_points.json --check 'outlier_vertices==40'

demo-denoise: demo-perturb
	$(GEO) denoise $(DEMO)/perturb_cube.ply --reference fixtures/data/cube.ply -o $(DEMO)/denoise_cube.ply --quiet --report $(DEMO)/denoise_cube.json --check 'mean_normal_angle_deg<=4' --check 'new_flipped_faces==0'
	$(PY) fixtures/denoise_fixtures.py $(DEMO)/denoise_inputs > /dev/null
	$(GEO) denoise $(DEMO)/denoise_inputs/cloud_outliers.ply --outliers --k 16 -o $(DEMO)/denoise_cloud_inliers.ply --quiet --report $(DEMO)/denoise_cloud.json --check 'f1>=0.85'
	$(GEO) denoise $(DEMO)/denoise_inputs/wave_noisy.npz --dynamic --reference $(DEMO)/denoise_inputs/wave_clean.npz -o $(DEMO)/denoise_wave.npz --quiet --report $(DEMO)/denoise_wave.json --check 'mean_normal_angle_deg<=12'

DEMO_STEPS := demo-info demo-morse-simplify demo-wos-solve demo-geodesic demo-perturb demo-denoise

demo-summary: $(DEMO_STEPS)
	$(PY) -m geoproc_cli.report_table $(DEMO)
	$(PY) -m geoproc_cli.report_table $(DEMO) --csv $(DEMO)/reports.csv

# ---- benchmarks against peer libraries (never part of `make test`) ----
# the bench extras alone, once per change of the package metadata: reinstalling the
# package on every run removed the editable install under a `make -j test bench`
BENCH_STAMP := $(VENV)/.bench-stamp

$(BENCH_STAMP): $(STAMP)
	$(PY) -c "import tomllib; print('\n'.join(tomllib.load(open('pyproject.toml', 'rb'))['project']['optional-dependencies']['bench']))" > $(VENV)/bench-requirements.txt
	$(PY) -m pip install --quiet -r $(VENV)/bench-requirements.txt
	touch $@

bench: $(BENCH_STAMP)
	@for script in bench/*.py; do echo "== $$script"; $(PY) $$script || exit 1; done

lint: $(STAMP)
	$(PY) -m ruff check geoproc cli tests fixtures bench

clean:
	rm -rf out fixtures/data .pytest_cache .ruff_cache build *.egg-info
	find . -name __pycache__ -type d -prune -exec rm -rf {} +
