#!/usr/bin/env bash
# Newcomer command #2: build .venv if needed, then run the test suite.
# Extra arguments go to pytest, e.g. `bash scripts/test.sh -q -m "not slow"`.
# CI runs `bash .ci/run`, which is `bash scripts/test.sh -q`.
set -euo pipefail
REPO_ROOT="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$REPO_ROOT"
bash scripts/setup_env.sh
exec .venv/bin/python -m pytest tests "$@"
