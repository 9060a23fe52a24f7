#!/usr/bin/env bash
# Opens the built site (make docs) in a real headless browser, Debian's chromium, and saves
# screenshots of the home page, the tasks' index and a task page, to look at before a
# release. Not part of CI (which does not install a browser).
#
#   docs/_scripts/screenshots.sh [OUT]     (OUT: /tmp/docs-shots by default)
set -euo pipefail
cd "$(dirname "$0")/../.."
OUT="${1:-/tmp/docs-shots}"
SITE="$PWD/docs/_build/html"
[ -f "$SITE/index.html" ] || { echo "no built site at $SITE: run make docs first" >&2; exit 1; }
if ! command -v chromium >/dev/null 2>&1; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq chromium >/dev/null
fi
mkdir -p "$OUT"
shot() {  # shot PAGE NAME WIDTH HEIGHT
  chromium --headless --no-sandbox --disable-gpu --hide-scrollbars --virtual-time-budget=3000 \
    --window-size="$3,$4" --screenshot="$OUT/$2.png" "file://$SITE/$1" 2>/dev/null
  echo "$OUT/$2.png"
}
shot index.html index 1280 1000
shot tasks/index.html tasks 1280 1000
shot tasks/push.html push 1280 3600
shot tasks/push.html push-narrow 420 1400
shot api.html api 1280 2400
