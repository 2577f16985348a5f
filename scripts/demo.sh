#!/usr/bin/env bash
# Run the strapdown demo from the project venv (set up on first use).
# Usage: scripts/demo.sh [strapdown_demo args...]
set -euo pipefail
ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
bash "$ROOT/scripts/setup_env.sh"
exec "$ROOT/.venv/bin/strapdown_demo" "$@"
