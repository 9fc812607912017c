# The league server image: `league serve` (the API) and `league worker` both run from it.
#   docker compose up --build --scale worker=3
# torch (for TorchScript uploads) from PyTorch's CPU index: the default index's brings CUDA
# libraries the league never uses. Installed from the source tree (-e): the server then hands
# students the sdist of its code too (GET /api/package), for machines unlike its own.
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 \
    LEAGUE_DATA_DIR=/data

# A C compiler for the simulator's Cython core.
RUN apt-get update && apt-get install -y --no-install-recommends build-essential \
    && rm -rf /var/lib/apt/lists/*

WORKDIR /app
COPY . /app
RUN pip install torch --index-url https://download.pytorch.org/whl/cpu \
    && pip install -e ".[server]" && mkdir -p /data  # the bundled baseline agents are package data

# Runs as root so that each sandbox can enter its own network namespace and then drop to a
# user id of its own (see league/server/sandbox/child.py); the API and workers never load a model.
VOLUME /data
EXPOSE 8000
CMD ["league", "serve", "--host", "0.0.0.0", "--port", "8000"]
