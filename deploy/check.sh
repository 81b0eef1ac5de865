#!/usr/bin/env bash
# Offline checks of deploy/: shell scripts through shellcheck, every YAML file through a
# YAML parser, the Kubernetes manifests against the API schemas with kubernetes-validate
# (strict: unknown fields fail), each where the tool is installed; says what it skipped.
#   pip install kubernetes-validate   # schemas bundled, no cluster needed
#   apt-get install shellcheck
set -euo pipefail
cd "$(dirname "${BASH_SOURCE[0]}")"
status=0
if command -v shellcheck >/dev/null; then
  shellcheck ./*.sh slurm/*.sh slurm/*.sbatch k8s/*.sh || status=1
  echo "shellcheck: done"
else
  echo "shellcheck: not installed, skipped"
fi
python3 - k8s/*.yaml <<'PY' || status=1
import sys, yaml
for path in sys.argv[1:]:
    with open(path) as f:
        docs = [d for d in yaml.safe_load_all(f) if d is not None]
    print(f"yaml: {path}: {', '.join(d['kind'] + '/' + d['metadata']['name'] for d in docs)}")
PY
if command -v kubernetes-validate >/dev/null; then
  # 1.29: the oldest release with backoffLimitPerIndex (beta there).
  for version in 1.29.0 1.33.0; do
    kubernetes-validate --strict --quiet -k "$version" k8s/*.yaml || status=1
  done
  echo "kubernetes-validate: done (1.29, 1.33)"
else
  echo "kubernetes-validate: not installed, skipped"
fi
exit "$status"
