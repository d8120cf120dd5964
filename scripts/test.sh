#!/usr/bin/env bash
# The test command of the README: installs what is missing (idempotent), then runs every test of the
# workspace against the real lavapipe and the real validation layer.
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/setup.sh
export VK_DRIVER_FILES=${VK_DRIVER_FILES:-/usr/share/vulkan/icd.d/lvp_icd.json}
cargo test --workspace --locked "$@"
