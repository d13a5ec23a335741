#!/usr/bin/python3
"""The command reference page equals what the binary prints.

    cli_reference_test.py BINARY PAGE

Checks, with the binary built from this tree:
  1. `BINARY --help-markdown` is byte for byte PAGE (the page was regenerated
     after the last option change: `bash scripts/update_cli_reference.sh`);
  2. the commands `BINARY --help` lists are the page's `## BINARY <command>`
     sections, no more, no fewer;
  3. each section's code block is byte for byte what `BINARY <command> --help`
     prints, run as a user runs it (so the page cannot drift from --help even
     if the Markdown generator itself were wrong).
Standard library only: it runs in every build (sanitizer builds included).
"""
import os
import re
import subprocess
import sys


def run(args):
    r = subprocess.run(args, capture_output=True, text=True, timeout=120)
    if r.returncode != 0:
        sys.exit(f"FAIL: {' '.join(args)} exited {r.returncode}: {r.stderr.strip()}")
    return r.stdout


def main():
    binary, page_path = sys.argv[1], sys.argv[2]
    name = os.path.basename(binary)
    page = open(page_path, encoding="utf-8").read()
    fix = f"regenerate it: bash scripts/update_cli_reference.sh"
    failures = []

    generated = run([binary, "--help-markdown"])
    if generated != page:
        failures.append(f"{page_path} differs from `{name} --help-markdown`; {fix}")

    top = run([binary, "--help"])
    listed = re.findall(r"^  ([a-z0-9][a-z0-9-]*)\s", top.split("Subcommands:", 1)[-1], re.M)
    sections = dict(re.findall(
        r"^## `" + re.escape(name) + r" ([a-z0-9-]+)`\n.*?```text\n(.*?)```\n",
        page, re.M | re.S))
    if not listed:
        failures.append(f"`{name} --help` lists no commands")
    if sorted(listed) != sorted(sections):
        failures.append(f"commands in `{name} --help` {sorted(listed)} != "
                        f"sections of {page_path} {sorted(sections)}; {fix}")
    for command in listed:
        text = run([binary, command, "--help"])
        if sections.get(command) != text:
            failures.append(f"`{name} {command} --help` differs from its "
                            f"section in {page_path}; {fix}")

    for f in failures:
        print("FAIL:", f)
    if failures:
        sys.exit(1)
    print(f"ok: {len(listed)} commands of {name}, each section equal to its --help")


if __name__ == "__main__":
    main()
