#!/usr/bin/env bash
# System packages the test suite needs: headless Chromium for the HTML report check.
# Installed here, by the tests' set-up, so a fresh machine needs nothing by hand.
set -u
if ! command -v chromium >/dev/null 2>&1; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    echo "tests/setup_system.sh: installing chromium and chromium-driver (Debian packages)"
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver) >/dev/null 2>&1 \
      || echo "tests/setup_system.sh: could not install chromium; the browser test will fail"
  else
    echo "tests/setup_system.sh: chromium missing and not root; the browser test will fail"
  fi
fi
exit 0
