# mlink-sim as a container: every station of a testbed in its own container, the master in another
# (docs/testbeds.md). Build:   docker build -t mlink-sim .
# Run one station:              docker run --rm -e MLINK_PROBE_TARGET=127.0.0.1:47001 -e MLINK_PROBE_STATION=0x21 \
#                                 mlink-sim slave --card si-t3 --station 0x21 --listen 0.0.0.0:47001
# A whole testbed:              mlink-sim compose configs/quickstart.toml -o compose.yaml
FROM python:3.11-slim

LABEL org.opencontainers.image.title="mlink-sim" \
      org.opencontainers.image.description="Real-time MECHATROLINK-I/II/III master/slave simulator over UDP" \
      org.opencontainers.image.licenses="MIT"

ENV PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1 \
    PIP_DISABLE_PIP_VERSION_CHECK=1 \
    PIP_NO_CACHE_DIR=1

# A fixed, non-root uid so that bind mounts and volumes have predictable owners. /reports and /state are created
# here, owned by that user: a named volume mounted on them starts with the same owner, so the master can write
# its report and a slave its EEPROM images without running as root.
RUN groupadd --system --gid 10001 mlink \
 && useradd --system --uid 10001 --gid mlink --home-dir /home/mlink --create-home --shell /usr/sbin/nologin mlink \
 && mkdir -p /reports /state /config \
 && chown mlink:mlink /reports /state

# Only what the build needs (.dockerignore keeps .venv, .git, caches, tests and docs out of the context).
COPY pyproject.toml README.md /tmp/src/
COPY mlink_sim /tmp/src/mlink_sim
RUN pip install --no-cache-dir /tmp/src \
 && rm -rf /tmp/src \
 && mlink-sim --version
# The example networks, for `docker run --rm mlink-sim up /usr/local/share/mlink-sim/configs/quickstart.toml`.
COPY configs /usr/local/share/mlink-sim/configs

USER mlink
WORKDIR /home/mlink

# The health of a station container is the station's own answer to a NOP. Set MLINK_PROBE_TARGET (HOST:PORT,
# usually 127.0.0.1:PORT) and MLINK_PROBE_STATION (e.g. 0x21) on station containers; MLINK_PROBE_ARGS adds
# probe options (e.g. "--link ml2 --frame-size 32"). Unset (the default, and the master's role) the check
# always passes. A card answers a NOP from any source with its status, also while a master is connected, and
# executes nothing for it (docs/cards.md), so the check follows the live station for the whole run.
ENV MLINK_PROBE_TARGET="" \
    MLINK_PROBE_STATION="" \
    MLINK_PROBE_ARGS=""
HEALTHCHECK --interval=2s --timeout=5s --start-period=10s --retries=5 \
    CMD [ -z "$MLINK_PROBE_TARGET" ] \
        || mlink-sim probe "$MLINK_PROBE_TARGET" --station "$MLINK_PROBE_STATION" --timeout 2 $MLINK_PROBE_ARGS

# UDP ports come from the command (--listen / --endpoint); nothing is exposed by default.
STOPSIGNAL SIGTERM
ENTRYPOINT ["mlink-sim"]
CMD ["--help"]
