#!/usr/bin/python3
"""Transport plugins keep their thread-locals in glibc's static TLS block.

A dlopen'ed module with thread-local variables (the kit's Asio call stack, read whenever a
handler is allocated) gets, by default, a heap block per thread reached through
__tls_get_addr. simgate_add_transport_plugin and the kit compile with
-ftls-model=initial-exec instead: a plain %fs access, and no per-thread heap block, which
GCC 12's LeakSanitizer misread at exit and crashed on (the socket tests under ASan).
Usage: plugin_tls_test.py PLUGIN.so...
"""
import subprocess
import sys


def readelf(*args):
    return subprocess.run(["readelf", "-W", *args], check=True, capture_output=True, text=True).stdout


def main(paths):
    failures = []
    checked = 0
    for path in paths:
        has_tls = any(line.split()[:1] == ["TLS"] for line in readelf("-l", path).splitlines())
        if not has_tls:
            continue
        checked += 1
        flags = [line for line in readelf("-d", path).splitlines() if "(FLAGS)" in line]
        if not any("STATIC_TLS" in line for line in flags):
            failures.append(f"{path}: has thread-local variables but no STATIC_TLS flag "
                            f"(built without -ftls-model=initial-exec?) flags: {flags}")
    for failure in failures:
        print("FAIL", failure)
    if checked == 0:
        print("FAIL no plugin with thread-local variables was given: the check checked nothing")
        return 1
    print(f"{checked} plugin(s) with thread-locals checked, {len(failures)} failure(s)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
