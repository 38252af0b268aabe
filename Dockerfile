# swarmshow web server: REST API, editor and 3D viewer on one port.
#   docker build -t swarmshow .
#   docker run -p 8000:8000 -v swarmshow-data:/data -e SWARMSHOW_TOKEN="$(openssl rand -hex 24)" swarmshow
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1

WORKDIR /opt/swarmshow
COPY pyproject.toml README.md ./
COPY formations ./formations
COPY sim ./sim
COPY app ./app
COPY frontend ./frontend
RUN pip install . \
    && useradd --system --uid 10001 --user-group --home-dir /data --shell /usr/sbin/nologin swarmshow \
    && mkdir -p /data \
    && chown swarmshow:swarmshow /data

# The store lives on the volume; caches go to /tmp because the installed package is read-only to the user.
ENV SWARMSHOW_DATA_DIR=/data \
    SWARMSHOW_STATIC_DIR=/opt/swarmshow/frontend \
    SWARMSHOW_PORT=8000 \
    NUMBA_CACHE_DIR=/tmp/numba-cache \
    MPLCONFIGDIR=/tmp/matplotlib \
    HOME=/data

USER swarmshow
VOLUME ["/data"]
EXPOSE 8000

# Off loopback the server requires SWARMSHOW_TOKEN (docker run -e SWARMSHOW_TOKEN=...), so the health check
# sends it. urllib raises (exit 1) on a refused connection or a non-2xx answer; no curl needed in the image.
HEALTHCHECK --interval=30s --timeout=5s --start-period=30s --retries=3 \
    CMD python -c "import os, urllib.request as u; u.urlopen(u.Request('http://127.0.0.1:%s/api/health' % os.environ.get('SWARMSHOW_PORT', '8000'), headers={'Authorization': 'Bearer ' + os.environ.get('SWARMSHOW_TOKEN', '')}), timeout=4)"

CMD ["swarmshow", "serve", "--host", "0.0.0.0"]
