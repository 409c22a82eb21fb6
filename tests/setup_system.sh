#!/usr/bin/env bash
# System packages the test suite needs: headless Chromium for the HTML report check,
# LinuxCNC (linuxcnc-uspace: its rs274 interpreter checks the part programs), and ads-client from
# npm (tests/ads_client: an ADS client we did not write checks the simulated PLC), and PostgreSQL
# (postgresql: the history tests start a throwaway server of their own, tests/pg_server.py), and
# poppler-utils (pdftoppm, pdftotext: the report PDF test turns its pages into images and text).
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
if ! command -v rs274 >/dev/null 2>&1; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    echo "tests/setup_system.sh: installing linuxcnc-uspace (Debian package; rs274 for the part-program test)"
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends linuxcnc-uspace) \
      >/dev/null 2>&1 || echo "tests/setup_system.sh: could not install linuxcnc-uspace; its tests skip"
  else
    echo "tests/setup_system.sh: rs274 missing and not root; the LinuxCNC tests skip"
  fi
fi
if ! ls /usr/lib/postgresql/*/bin/initdb >/dev/null 2>&1; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    echo "tests/setup_system.sh: installing postgresql (Debian package; the history tests start a throwaway server)"
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends postgresql) \
      >/dev/null 2>&1 || echo "tests/setup_system.sh: could not install postgresql; the PostgreSQL history tests skip"
  else
    echo "tests/setup_system.sh: postgresql missing and not root; the PostgreSQL history tests skip"
  fi
fi
if ! command -v pdftoppm >/dev/null 2>&1; then
  if [ "$(id -u)" = "0" ] && command -v apt-get >/dev/null 2>&1; then
    echo "tests/setup_system.sh: installing poppler-utils (Debian package; pdftoppm and pdftotext check the report PDF)"
    (apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends poppler-utils) \
      >/dev/null 2>&1 || echo "tests/setup_system.sh: could not install poppler-utils; the PDF test will fail"
  else
    echo "tests/setup_system.sh: pdftoppm missing and not root; the PDF test will fail"
  fi
fi
if [ ! -d tests/ads_client/node_modules/ads-client ]; then
  if command -v npm >/dev/null 2>&1; then
    echo "tests/setup_system.sh: installing ads-client (npm) into tests/ads_client"
    (cd tests/ads_client && npm ci --no-audit --no-fund) >/dev/null 2>&1 \
      || echo "tests/setup_system.sh: could not install ads-client; the ADS fidelity tests skip"
  else
    echo "tests/setup_system.sh: npm missing; the ADS fidelity tests skip"
  fi
fi
exit 0
