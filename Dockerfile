# scm-calib: one image for the API, the Celery workers, the reaper (beat) and migrations.
FROM python:3.11-slim

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_NO_CACHE_DIR=1 \
    NUMBA_CACHE_DIR=/var/cache/numba \
    SCM_CALIB_DATA_DIR=/data

WORKDIR /app
COPY pyproject.toml README.md ./
COPY scm_core ./scm_core
COPY services ./services
COPY worker ./worker
COPY migrations ./migrations
COPY examples ./examples
RUN pip install -e . \
    && mkdir -p /var/cache/numba /data \
    # compile the simulator once into the image's numba cache: workers never recompile
    && python -c "from scm_core.simulator import RigConfig, SoilParams, simulate_swt, simulate_batch; \
r = RigConfig(duration=2.0, offset_F=1.0, offset_T=1.0, offset_z=0.5); simulate_swt(rig=r); \
simulate_batch([SoilParams()], rigs=r)"

EXPOSE 8000
CMD ["scm-calib", "serve", "--host", "0.0.0.0", "--port", "8000"]
