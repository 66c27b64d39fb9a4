# mlink-sim as a container: every station of a testbed in its own container, the master in another
# (docs/testbeds.md). Two ways to build it:
#   with a registry and the package index:  docker build -t mlink-sim .
#   offline (no registry, no index):       scripts/docker-build      (= scripts/docker-base, host-built wheels and
#                                             docker build --build-arg BASE=mlink-sim-base:bookworm
#                                                          --build-arg WHEELS=.docker-wheels -t mlink-sim .)
# Run one station:  docker run --rm -e MLINK_PROBE_TARGET=127.0.0.1:47001 -e MLINK_PROBE_STATION=0x21 \
#                     mlink-sim slave --card si-t3 --station 0x21 --listen 0.0.0.0:47001
# A whole testbed:  scripts/docker-testbed configs/quickstart.toml
#
# Written for the classic builder as well as BuildKit (no `# syntax`, no RUN --mount): Debian's docker.io has no
# buildx. BASE is any image with Python >= 3.11 and its venv module (python3 -m venv) on the PATH as python3.
ARG BASE=python:3.11-slim

# -- build: a virtual environment with mlink-sim and its dependencies, nothing else ------------------------------
FROM ${BASE} AS build
# WHEELS: a directory of the build context made by scripts/docker-build on the host with `pip wheel`: deps/ holds
# every dependency's wheel and requirements.txt (pyproject.toml's dependencies), project/ the project's wheel.
# Set, the install uses only those (--no-index), the dependencies in a layer of their own that the next build
# reuses while they stay the same. Empty (the default), pip installs from source with the package index.
ARG WHEELS=""
ENV PIP_DISABLE_PIP_VERSION_CHECK=1 \
    PIP_NO_CACHE_DIR=1 \
    PYTHONDONTWRITEBYTECODE=1
# A COPY needs a source that exists: pyproject.toml is copied along and ignored (a change to it may change the
# dependencies, so it may as well invalidate their layer).
COPY pyproject.toml ${WHEELS:+$WHEELS/deps} /tmp/deps/
RUN python3 -m venv /opt/mlink-sim \
 && if [ -n "$WHEELS" ]; then \
      /opt/mlink-sim/bin/pip install --no-index --find-links /tmp/deps -r /tmp/deps/requirements.txt; \
    fi
COPY pyproject.toml ${WHEELS:+$WHEELS/project} /tmp/project/
COPY pyproject.toml README.md setup.py /tmp/src/
COPY mlink_sim /tmp/src/mlink_sim
# mlink-health, the health check: the stdlib-only probe of mlink_sim/testbed/health.py run without site (-IS) and
# imported from the .pyc pip compiled, so a probe costs little more than the interpreter's start-up (~15 ms of CPU,
# where `mlink-sim probe` takes 0.2-0.7 s; docs/testbeds.md). The last line checks that it runs: nothing listens
# on port 9, so it must say that no answer came.
RUN if [ -n "$WHEELS" ]; then \
      /opt/mlink-sim/bin/pip install --no-index --no-deps /tmp/project/mlink_sim-*.whl; \
    else \
      /opt/mlink-sim/bin/pip install /tmp/src; \
    fi \
 && /opt/mlink-sim/bin/pip uninstall --yes --quiet pip setuptools \
 && /opt/mlink-sim/bin/mlink-sim --version \
 && printf '#!/opt/mlink-sim/bin/python3 -IS\nimport sys\nsys.path[0] = "%s"\nfrom health import main\nsys.exit(main())\n' \
      /opt/mlink-sim/lib/python3*/site-packages/mlink_sim/testbed > /opt/mlink-sim/bin/mlink-health \
 && chmod 0755 /opt/mlink-sim/bin/mlink-health \
 && /opt/mlink-sim/bin/mlink-health 127.0.0.1:9 --station 0x21 --timeout 0.1 2>&1 | grep -q "no valid NOP answer"

# -- runtime: the base, a non-root user and the virtual environment ---------------------------------------------
FROM ${BASE}

LABEL org.opencontainers.image.title="mlink-sim" \
      org.opencontainers.image.description="Real-time MECHATROLINK-I/II/III master/slave simulator over UDP" \
      org.opencontainers.image.licenses="MIT"

ENV PATH=/opt/mlink-sim/bin:$PATH \
    PYTHONDONTWRITEBYTECODE=1 \
    PYTHONUNBUFFERED=1

# A fixed, non-root uid so that bind mounts and volumes have predictable owners. /reports and /state are created
# here, owned by that user: a named volume mounted on them starts with the same owner, so the master can write
# its report and a slave its EEPROM images without running as root.
RUN groupadd --system --gid 10001 mlink \
 && useradd --system --uid 10001 --gid mlink --home-dir /home/mlink --create-home --shell /usr/sbin/nologin mlink \
 && mkdir -p /reports /state /config \
 && chown mlink:mlink /reports /state

COPY --from=build /opt/mlink-sim /opt/mlink-sim
# The example networks, for `docker run --rm mlink-sim up /usr/local/share/mlink-sim/configs/quickstart.toml`.
COPY mlink_sim/examples /usr/local/share/mlink-sim/configs

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
HEALTHCHECK --interval=5s --timeout=5s --start-period=30s --retries=3 \
    CMD [ -z "$MLINK_PROBE_TARGET" ] \
        || mlink-health "$MLINK_PROBE_TARGET" --station "$MLINK_PROBE_STATION" --timeout 2 $MLINK_PROBE_ARGS

# UDP ports come from the command (--listen / --endpoint); nothing is exposed by default.
STOPSIGNAL SIGTERM
ENTRYPOINT ["mlink-sim"]
CMD ["--help"]
