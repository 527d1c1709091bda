#!/usr/bin/env bash
# Install what the test suite needs beyond pip: Debian's chromium, for the browser tests of
# 'panomap learn' (tests/test_learn_browser.py drives it with Playwright; never
# 'playwright install', which downloads its own browsers). Idempotent and quiet: does
# nothing when /usr/bin/chromium is there. Needs root, or sudo.
set -euo pipefail

if [ -x /usr/bin/chromium ]; then
    exit 0
fi
if [ "$(id -u)" -eq 0 ]; then
    as_root=()
elif command -v sudo >/dev/null 2>&1; then
    as_root=(sudo)
else
    echo "install-test-deps: /usr/bin/chromium is missing and installing it needs root or sudo" >&2
    exit 1
fi
if ! command -v apt-get >/dev/null 2>&1; then
    echo "install-test-deps: /usr/bin/chromium is missing and this is not a Debian-like system (no apt-get);" \
        "install Chromium so that /usr/bin/chromium runs it" >&2
    exit 1
fi
export DEBIAN_FRONTEND=noninteractive
"${as_root[@]}" apt-get update -qq >/dev/null
"${as_root[@]}" apt-get install -y -qq --no-install-recommends chromium >/dev/null
test -x /usr/bin/chromium
