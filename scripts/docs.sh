#!/usr/bin/env bash
# Builds the documentation site into site/ (or the folder given as $1), warnings as errors.
# The tools are the `docs` extra: python -m pip install -e '.[docs]'.
# The generated pages (API reference, tutorials, changelog, result images) are written by
# docs/gen_pages.py inside the build (mkdocs-gen-files); nothing else needs to run first.
set -euo pipefail
cd "$(dirname "$0")/.."
export MUJOCO_GL="${MUJOCO_GL:-egl}"
# MkDocs' and Material's notices about their future releases are not warnings about this site.
export NO_MKDOCS_2_WARNING=1 DISABLE_MKDOCS_2_WARNING=true
exec python -m mkdocs build --strict --site-dir "${1:-site}"
