# skisnow service image: multi-stage, slim, non-root (uid and gid 10001), tables baked in and
# read-only for the service user.
# Build: docker build -t skisnow .    Run: docker run -p 8000:8000 skisnow
# CI builds and runs it with scripts/docker_ci.sh (docs/deployment.md).
#
# Layers, so that a code edit does not reinstall the dependencies:
#   reqs     the dependency list, read from pyproject.toml (only its list reaches the next stage:
#            an edit elsewhere in pyproject.toml keeps the dependency layer cached);
#   build    /opt/venv: the dependencies alone; /opt/skisnow: app/, solvers/ and the tables
#            (package data skisnow.tables), installed without dependencies;
#   runtime  /opt/venv and /opt/skisnow copied as two layers (a code edit changes the small one).
FROM python:3.11-slim AS reqs
WORKDIR /src
COPY pyproject.toml ./
RUN python -c "import tomllib; p = tomllib.load(open('pyproject.toml', 'rb')); \
print('\n'.join(p['project']['dependencies'] + p['build-system']['requires']))" \
    > /requirements.txt

FROM python:3.11-slim AS build
WORKDIR /src
ENV PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1
COPY --from=reqs /requirements.txt /requirements.txt
# exact versions (the ranges of pyproject.toml would install whatever is newest on the day)
COPY scripts/docker-constraints.txt /constraints.txt
# the dependencies (and setuptools/wheel to build the package below without a download); test
# suites of the largest dependencies removed (about 100 MB, never imported by the service)
RUN python -m venv /opt/venv \
    && /opt/venv/bin/pip install -r /requirements.txt -c /constraints.txt \
    && cd /opt/venv/lib/python3.*/site-packages \
    && rm -rf numpy/*/tests numpy/tests scipy/*/tests scipy/*/*/tests matplotlib/tests \
              numba/tests pandas/tests SurfaceTopography/*/tests
COPY README.md pyproject.toml ./
COPY app ./app
COPY solvers ./solvers
COPY tables ./tables
RUN /opt/venv/bin/pip install --no-deps --no-build-isolation --target /opt/skisnow . \
    && rm -rf build *.egg-info
# numba's compiled kernels, cached once here: every first start of a container (each worker)
# would otherwise compile them again (a fresh container was ready in 48 s, 8 s with the cache;
# docs/deployment.md). The cache is keyed on the CPU: another CPU model compiles and re-caches.
ENV NUMBA_CACHE_DIR=/opt/numba-cache NUMBA_NUM_THREADS=1 OMP_NUM_THREADS=1
RUN cd /tmp && PYTHONPATH=/opt/skisnow /opt/skisnow/bin/skisnow solve --ski ski-a \
        --grind grind-1 --load-kg 40 --load-position-mm -160 --snow-modulus-mpa 200 \
        --porosity 0.5 >/dev/null

FROM python:3.11-slim AS runtime
ENV PATH=/opt/skisnow/bin:/opt/venv/bin:$PATH \
    PYTHONPATH=/opt/skisnow \
    PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    SKISNOW_HOST=0.0.0.0 \
    SKISNOW_PORT=8000 \
    SKISNOW_WORKERS=2 \
    SKISNOW_THREADS_PER_WORKER=1 \
    SKISNOW_DATA_DIR=/srv/skisnow/data \
    OMP_NUM_THREADS=1 \
    OPENBLAS_NUM_THREADS=1 \
    MKL_NUM_THREADS=1 \
    NUMBA_NUM_THREADS=1 \
    NUMBA_CACHE_DIR=/opt/numba-cache \
    MPLCONFIGDIR=/tmp/matplotlib
# fixed ids (a bind-mounted data folder must be owned by 10001:10001: docs/deployment.md)
RUN groupadd --gid 10001 skisnow \
    && useradd --uid 10001 --gid 10001 --no-create-home --home-dir /srv/skisnow \
               --shell /usr/sbin/nologin skisnow \
    && mkdir -p /srv/skisnow/data && chown 10001:10001 /srv/skisnow/data
# owned by root, not writable by the service user
COPY --from=build /opt/venv /opt/venv
COPY --from=build /opt/skisnow /opt/skisnow
# the one folder of /opt the service user writes: numba re-caches what the CPU cannot reuse
COPY --from=build --chown=10001:10001 /opt/numba-cache /opt/numba-cache
USER 10001:10001
WORKDIR /srv/skisnow
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=3s --start-period=20s --retries=3 \
    CMD python -c "import os,sys,urllib.request; port = os.environ.get('SKISNOW_PORT', '8000'); sys.exit(0 if urllib.request.urlopen(f'http://127.0.0.1:{port}/healthz', timeout=2).status == 200 else 1)"
# uploaded skis/grinds and the catalogue database: mount a volume here to keep them
VOLUME /srv/skisnow/data
CMD ["skisnow", "serve"]
