# skisnow service image: multi-stage, slim, non-root, tables baked in (inside the installed
# package: pyproject.toml ships tables/ as package data, found without SKISNOW_TABLES_DIR; set
# it to serve other tables, e.g. a mounted volume).
# Build: docker build -t skisnow .    Run: docker run -p 8000:8000 skisnow
FROM python:3.11-slim AS build
WORKDIR /src
ENV PIP_NO_CACHE_DIR=1 PIP_DISABLE_PIP_VERSION_CHECK=1
COPY pyproject.toml README.md ./
COPY app ./app
COPY solvers ./solvers
COPY tables ./tables
RUN python -m venv /opt/venv \
    && /opt/venv/bin/pip install --upgrade pip \
    && /opt/venv/bin/pip install .

FROM python:3.11-slim AS runtime
ENV PATH=/opt/venv/bin:$PATH \
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
    NUMBA_CACHE_DIR=/tmp/numba-cache \
    MPLCONFIGDIR=/tmp/matplotlib
RUN useradd --system --uid 10001 --home-dir /srv/skisnow skisnow \
    && mkdir -p /srv/skisnow/data && chown skisnow:skisnow /srv/skisnow/data
COPY --from=build /opt/venv /opt/venv
USER skisnow
WORKDIR /srv/skisnow
EXPOSE 8000
HEALTHCHECK --interval=30s --timeout=3s --start-period=20s --retries=3 \
    CMD python -c "import os,sys,urllib.request; port = os.environ.get('SKISNOW_PORT', '8000'); sys.exit(0 if urllib.request.urlopen(f'http://127.0.0.1:{port}/healthz', timeout=2).status == 200 else 1)"
# uploaded skis/grinds and the catalogue database: mount a volume here to keep them
VOLUME /srv/skisnow/data
CMD ["skisnow", "serve"]
