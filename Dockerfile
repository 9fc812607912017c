# The league server image: `league serve` (the API) and `league worker` both run from it.
#   docker compose up -d --build --scale worker=3   (docker-compose.yml; league/server/README.md)
# Installed from the source tree (-e): the server then hands students the sdist of its code too
# (GET /api/package), for machines unlike its own. Its pages and baseline agents are package data.
FROM python:3.11.10-slim-bookworm

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 \
    LEAGUE_DATA_DIR=/data

WORKDIR /app
COPY . /app
# torch runs TorchScript uploads: the CPU build from PyTorch's CPU index (the default index's
# brings GBs of CUDA libraries the league never uses), the release the test suite runs (README.md).
# The C compiler builds the simulator's Cython core, then goes (the sdist the server hands out needs
# none: the server extra's Cython writes its C file); libseccomp2 confines the sandboxes.
RUN apt-get update && apt-get install -y --no-install-recommends build-essential libseccomp2 \
    && pip install torch==2.13.0 --index-url https://download.pytorch.org/whl/cpu \
    && pip install -e ".[server]" \
    && apt-get purge -y --auto-remove build-essential && rm -rf /var/lib/apt/lists/*

# The API and the admin commands run as this user. The worker runs as root (docker-compose.yml says
# why: each sandbox takes a user id of its own) with only the capabilities that needs.
RUN useradd --system --uid 10001 --home-dir /data --shell /usr/sbin/nologin league \
    && mkdir -p /data && chown league:league /data
USER league
VOLUME /data
EXPOSE 8000
CMD ["league", "serve", "--host", "0.0.0.0", "--port", "8000"]
