#!/usr/bin/env bash
# The dependency script must do nothing when every package is present, and must call apt-get
# (update, then install of exactly the missing packages) when one is missing.
set -u
export PATH="/usr/bin:/bin:$PATH"
src="${1:?usage: test_install_deps.sh SOURCE_DIR}"
script="$src/scripts/install-deps"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
failures=0
check() { if eval "$2"; then echo "PASS: $1"; else echo "FAIL: $1"; failures=$((failures + 1)); fi; }

# A stand-in apt-get that records its calls instead of installing anything.
cat > "$tmp/fake-apt-get" <<FAKE
#!/usr/bin/env bash
echo "\$*" >> "$tmp/apt-calls"
FAKE
chmod +x "$tmp/fake-apt-get"

# 1. The real list, everything installed (the build got here, so it is): no apt-get call.
out=$(APT_GET="$tmp/fake-apt-get" "$script" 2>&1); rc=$?
check "all present exits 0" "[ $rc -eq 0 ]"
check "all present says so" "grep -q 'all .* present' <<<\"\$out\""
check "all present calls no apt-get" "[ ! -e '$tmp/apt-calls' ]"

# 2. A list with one installed and one missing package: apt-get installs only the missing one.
printf '# comment\nbash  # installed everywhere\n\ntabletop-shapes-no-such-package\n' > "$tmp/list"
if [ "$(id -u)" -eq 0 ] || sudo -n true 2>/dev/null; then
  out=$(DEPS_LIST="$tmp/list" APT_GET="$tmp/fake-apt-get" "$script" 2>&1); rc=$?
  check "missing package exits 0" "[ $rc -eq 0 ]"
  check "apt-get update called" "grep -q '^update' '$tmp/apt-calls'"
  check "only the missing package installed" \
    "grep -q 'install .*tabletop-shapes-no-such-package' '$tmp/apt-calls' && ! grep -q 'install.* bash' '$tmp/apt-calls'"
else
  echo "SKIP: not root and no passwordless sudo: checking the clear refusal instead"
  out=$(DEPS_LIST="$tmp/list" APT_GET="$tmp/fake-apt-get" "$script" 2>&1); rc=$?
  check "refuses with exit 1" "[ $rc -eq 1 ]"
  check "says how to install" "grep -q 'apt-get install tabletop-shapes-no-such-package' <<<\"\$out\""
fi

# 3. --list prints the package names without comments or blanks.
check "--list drops comments" "[ \"\$(DEPS_LIST='$tmp/list' '$script' --list | tr '\n' ' ')\" = 'bash tabletop-shapes-no-such-package ' ]"

echo "$((failures == 0 ? 1 : 0)) passed, $failures failed" >/dev/null
[ $failures -eq 0 ]
