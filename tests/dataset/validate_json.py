#!/usr/bin/python3
"""Validates JSON documents (or JSON-lines files with --jsonl) against a JSON Schema with the
real `jsonschema` validator (Debian python3-jsonschema), draft 2020-12. Exit 0 when valid."""
import json
import sys

import jsonschema


def main():
    args = sys.argv[1:]
    jsonl = "--jsonl" in args
    args = [a for a in args if a != "--jsonl"]
    schema = json.load(open(args[0]))
    jsonschema.Draft202012Validator.check_schema(schema)
    validator = jsonschema.Draft202012Validator(schema)
    count = 0
    for path in args[1:]:
        docs = []
        if jsonl:
            docs = [json.loads(l) for l in open(path) if l.strip()]
        else:
            docs = [json.load(open(path))]
        for doc in docs:
            errors = sorted(validator.iter_errors(doc), key=lambda e: e.path)
            if errors:
                print(f"{path}: {errors[0].message} at {list(errors[0].path)}")
                sys.exit(1)
            count += 1
    print(f"validated {count} document(s)")


if __name__ == "__main__":
    main()
