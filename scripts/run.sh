#!/usr/bin/env bash
# Set everything up and run the main job: the server with the simulated demo site.
# Extra arguments go to `irloc serve` (see `irloc serve --help`).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
exec .venv/bin/irloc serve "$@"
