#!/usr/bin/python3
"""Transport plugins keep their thread-locals in glibc's static TLS block.

A dlopen'ed module with thread-local variables (the kit's Asio call stack, read whenever a
handler is allocated) gets, by default, a heap block per thread reached through
__tls_get_addr. simgate_add_transport_plugin and the kit compile with
-ftls-model=initial-exec instead: a plain %fs access, and no per-thread heap block, which
GCC 12's LeakSanitizer misread at exit and crashed on (the socket tests under ASan).

That block is small: glibc keeps 512 bytes of it (the tunable glibc.rtld.optional_static_tls)
for every module dlopen'ed with initial-exec TLS, and a gateway loads all its transports into
one process. Past it, dlopen fails with "cannot allocate memory in static TLS block" (it did
once a fourth plugin carried Beast's 160 bytes of WebSocket mask generators: the kit's unity
batch put them in every plugin). So the shipped plugins' static TLS, together, stays within
STATIC_TLS_BUDGET.
Usage: plugin_tls_test.py PLUGIN.so...
"""
import subprocess
import sys


def readelf(*args):
    return subprocess.run(["readelf", "-W", *args], check=True, capture_output=True, text=True).stdout


# Bytes of static TLS all the shipped plugins may take together (of glibc's 512: the rest
# for alignment and for what else a process dlopens, MuJoCo's engine plugins among them).
STATIC_TLS_BUDGET = 384


def tls_size(path):
    """The memory size of the module's TLS segment (0 without one), rounded up to 16."""
    for line in readelf("-l", path).splitlines():
        fields = line.split()
        if fields[:1] == ["TLS"]:
            return (int(fields[5], 16) + 15) // 16 * 16
    return 0


def main(paths):
    failures = []
    checked = 0
    total = 0
    for path in paths:
        size = tls_size(path)
        total += size
        if size == 0:
            continue
        checked += 1
        flags = [line for line in readelf("-d", path).splitlines() if "(FLAGS)" in line]
        if not any("STATIC_TLS" in line for line in flags):
            failures.append(f"{path}: has thread-local variables but no STATIC_TLS flag "
                            f"(built without -ftls-model=initial-exec?) flags: {flags}")
    if total > STATIC_TLS_BUDGET:
        failures.append(f"the plugins take {total} bytes of static TLS together, over the "
                        f"{STATIC_TLS_BUDGET} a gateway that loads them all can count on: "
                        + ", ".join(f"{p}: {tls_size(p)}" for p in paths))
    for failure in failures:
        print("FAIL", failure)
    if checked == 0:
        print("FAIL no plugin with thread-local variables was given: the check checked nothing")
        return 1
    print(f"{checked} plugin(s) with thread-locals checked, {total} bytes of static TLS "
          f"together (budget {STATIC_TLS_BUDGET}), {len(failures)} failure(s)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
