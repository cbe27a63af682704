#!/bin/sh
# Install Debian's chromium for the report browser test (tests/test_report_browser.py), if missing.
# Idempotent; never fails the build: without chromium that test skips and says why.
set -u
if [ -x /usr/bin/chromium ]; then
    exit 0
fi
if [ "$(id -u)" != "0" ]; then
    echo "ensure_chromium: /usr/bin/chromium is missing and this is not root; the browser test will skip" \
         "(install it with: sudo apt-get install -y chromium)" >&2
    exit 0
fi
if ! command -v apt-get >/dev/null 2>&1; then
    echo "ensure_chromium: /usr/bin/chromium is missing and there is no apt-get; the browser test will skip" >&2
    exit 0
fi
echo "ensure_chromium: installing Debian's chromium for the report browser test" >&2
if ! { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null; }; then
    echo "ensure_chromium: apt-get could not install chromium; the browser test will skip" >&2
fi
exit 0
