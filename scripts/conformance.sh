#!/usr/bin/env bash
# The main command of the README: installs what is missing (idempotent), then runs the default
# conformance run on lavapipe under the validation layer. Extra arguments go to `rtconf run`.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export VK_DRIVER_FILES=${VK_DRIVER_FILES:-/usr/share/vulkan/icd.d/lvp_icd.json}
cargo run --release --locked -q -p rtconf-cli --bin rtconf -- run --driver lavapipe --out out/lavapipe "$@"
