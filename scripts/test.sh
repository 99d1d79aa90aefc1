#!/usr/bin/env bash
# Set everything up and run the test suite. Extra arguments go to pytest.
# The browser tests need Debian's Chromium, the PostgreSQL tests Debian's PostgreSQL server
# binaries and the fleet tests Debian's Mosquitto broker: as root with apt available (CI) they are installed here; elsewhere those tests are
# skipped with a message saying how to install them.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
if ! command -v chromium >/dev/null 2>&1 && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  echo "installing Debian's chromium for the browser tests..."
  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null) \
    || echo "warning: could not install chromium; browser tests will be skipped" >&2
fi
if ! ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1 && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  echo "installing Debian's postgresql for the PostgreSQL tests..."
  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq postgresql >/dev/null) \
    || echo "warning: could not install postgresql; PostgreSQL tests will be skipped" >&2
fi
if ! command -v mosquitto >/dev/null 2>&1 && [ ! -x /usr/sbin/mosquitto ] && [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
  echo "installing Debian's mosquitto for the fleet (MQTT) tests..."
  (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq mosquitto >/dev/null) \
    || echo "warning: could not install mosquitto; fleet tests will be skipped" >&2
fi
echo "checking the layering (import-linter contracts in pyproject.toml)..."
PYTHONPATH="$PWD" .venv/bin/lint-imports
echo "type-checking every package (mypy strict)..."
.venv/bin/mypy pubsub localizer lighting sim recording rf_gateway calibration commissioning fleet sensors store survey agent export live server web irloc ros2
set +e
# Two workers (pytest-xdist), a test file each at a time: most of the suite waits on live
# servers, browsers and sockets, so two share the CI's two cores well (about half the serial
# time). IRLOC_TEST_WORKERS=0 runs in one process; a later -n among the arguments wins.
.venv/bin/python -m pytest -n "${IRLOC_TEST_WORKERS:-2}" --dist loadfile --durations=30 --durations-min=5 "$@"
status=$?
set -e
# pytest's exit status 5 means "no tests collected": that is a failure of the suite here.
exit $status
