# The league server image: `league serve` (the API) and `league worker` both run from it.
#   docker compose up --build --scale worker=3
# torch from the default index brings CUDA libraries; point pip at a CPU-only wheel index to
# slim the image (the league never uses a GPU).
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 PYTHONUNBUFFERED=1 PIP_NO_CACHE_DIR=1 \
    LEAGUE_DATA_DIR=/data

# A C compiler for the simulator's Cython core.
RUN apt-get update && apt-get install -y --no-install-recommends build-essential \
    && rm -rf /var/lib/apt/lists/*

WORKDIR /app
COPY . /app
RUN pip install ".[server,torch]" && mkdir -p /data  # the bundled baseline agents are package data

# Runs as root so that each sandbox can enter its own network namespace and then drop to a
# user id of its own (see league/server/sandbox/child.py); the API and workers never load a model.
VOLUME /data
EXPOSE 8000
CMD ["league", "serve", "--host", "0.0.0.0", "--port", "8000"]
