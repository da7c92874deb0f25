#!/usr/bin/env python3
"""GatewaySchema: config/schema/deployment.schema.json is a valid JSON Schema (draft
2020-12), every shipped deployment (config/, tests/, and the JSON examples in README.md and
docs/) validates against it, typical mistakes are refused (and what is near them accepted),
and the schema's option keys for the built-in transports are exactly the keys each plugin
declares. The validator is Debian's
python3-jsonschema (nobody on the team wrote it).

usage: schema_test.py SOURCE_DIR"""
import glob
import json
import os
import re
import sys

import jsonschema

source = sys.argv[1]
with open(os.path.join(source, "config/schema/deployment.schema.json")) as f:
    schema = json.load(f)
jsonschema.Draft202012Validator.check_schema(schema)
validator = jsonschema.Draft202012Validator(schema)
failures = []


def errors_of(document):
    return [f"{'/'.join(map(str, e.absolute_path)) or '(root)'}: {e.message}" for e in validator.iter_errors(document)]


def is_deployment(document):
    return isinstance(document, dict) and "scene" in document and "transports" in document


# every shipped deployment file
shipped = sorted(glob.glob(os.path.join(source, "config/**/*.json"), recursive=True) +
                 glob.glob(os.path.join(source, "tests/**/*.json"), recursive=True))
checked = 0
for path in shipped:
    if "node_modules" in path or path.endswith("schema.json"):
        continue
    with open(path) as f:
        try:
            document = json.load(f)
        except json.JSONDecodeError:
            continue  # deliberately broken test inputs
    if not is_deployment(document):
        continue
    checked += 1
    for e in errors_of(document):
        failures.append(f"{os.path.relpath(path, source)}: {e}")
if checked < 3:
    failures.append(f"only {checked} shipped deployment files found")

# the examples in the docs (```json blocks that are whole deployments)
for path in [os.path.join(source, "README.md")] + sorted(glob.glob(os.path.join(source, "docs/**/*.md"), recursive=True)):
    with open(path) as f:
        text = f.read()
    for block in re.findall(r"```json\n(.*?)```", text, re.S):
        try:
            document = json.loads(block)
        except json.JSONDecodeError:
            continue  # fragments with "..." are not whole files
        if not is_deployment(document):
            continue
        checked += 1
        for e in errors_of(document):
            failures.append(f"{os.path.relpath(path, source)} (example): {e}")

# typical mistakes are refused
with open(os.path.join(source, "config/demo.json")) as f:
    demo = json.load(f)
mistakes = {
    "unknown top-level key": lambda c: c.update(robtos=[]),
    "worlds zero": lambda c: c.update(worlds=0),
    "worlds object key typo": lambda c: c.update(worlds={"count": 2, "maximum": 4}),
    "worlds threads negative": lambda c: c.update(worlds={"count": 2, "threads": -1}),
    "worlds scene of world 0": lambda c: c.update(worlds={"count": 2, "scenes": {"0": "moon.xml"}}),
    "worlds scene key not an index": lambda c: c.update(worlds={"count": 2, "scenes": {"w1": "moon.xml"}}),
    "worlds scene not a file name": lambda c: c.update(worlds={"count": 2, "scenes": {"1": 5}}),
    "scene missing": lambda c: c.pop("scene"),
    "timestep negative": lambda c: c["scene"].update(timestep=-1),
    "realtime factor word": lambda c: c["scene"].update(realtime_factor="fast"),
    "start_paused as a word": lambda c: c["scene"].update(start_paused="yes"),
    "socket option typo": lambda c: c["transports"]["socket"]["options"].update(prot=4000),
    "port out of range": lambda c: c["transports"]["socket"]["options"].update(port=70000),
    "socket option under its old and new name": lambda c: c["transports"]["socket"]["options"].update(
        max_clients=8, max_connections=8),
    "reserved robot name": lambda c: c["robots"][1].update(name="simulation"),
    "dotted component name": lambda c: c["robots"][0]["components"][0].update(name="mo.tion"),
    "component without type": lambda c: c["robots"][0]["components"][0].pop("type"),
    "waypoint option typo": lambda c: c["robots"][0]["components"][1]["options"].update(max_sped=1),
    "ground_robot option typo": lambda c: c["robots"][0]["options"].update(wheel_raidus=0.1),
    "log level word": lambda c: c.update(log_level="loud"),
    "services value not a list": lambda c: c["services"].update(default="socket"),
    "streams rule object without transports": lambda c: c["streams"].update(simulation={"frequency": 30}),
    "streams rule frequency zero": lambda c: c["streams"].update(simulation={"transports": ["socket"], "frequency": 0}),
    "streams rule object key typo": lambda c: c["streams"].update(simulation={"transports": ["socket"], "rate": 30}),
    "streams rule a word": lambda c: c["streams"].update(simulation="socket"),
    "deny not a list": lambda c: c["transports"]["socket"].update(deny="simulation.quit"),
    "deny pattern without a service": lambda c: c["transports"]["socket"].update(deny=["simulation"]),
    "allow pattern with an empty name": lambda c: c["transports"]["socket"].update(allow=["robot..motion.*"]),
    "allow pattern with a character no name has": lambda c: c["transports"]["socket"].update(allow=["robot.mo?ion"]),
}
for name, mistake in mistakes.items():
    document = json.loads(json.dumps(demo))
    mistake(document)
    if not errors_of(document):
        failures.append(f"the schema accepts a config with: {name}")

# what a mistake could be mistaken for is accepted
accepted = {
    "worlds with scenes": lambda c: c.update(worlds={"count": 12, "scenes": {"2": "moon.xml", "11": "/abs/other.xml"}}),
}
for name, change in accepted.items():
    document = json.loads(json.dumps(demo))
    change(document)
    for e in errors_of(document):
        failures.append(f"the schema refuses a config with {name}: {e}")

# the built-in transports' option keys: the schema's and the plugin's declared ones agree
for plugin, source_file in [("socket", "plugins/socket/socket_request_manager.cc"),
                            ("jsonrpc", "plugins/jsonrpc/jsonrpc_request_manager.cc"),
                            ("dds", "plugins/dds/dds_request_manager.cc"),
                            ("websocket", "plugins/websocket/websocket_request_manager.cc"),
                            ("foxglove", "plugins/foxglove/foxglove_server.cc")]:
    with open(os.path.join(source, source_file)) as f:
        text = f.read()
    match = re.search(r"SIMGATE_TRANSPORT_PLUGIN\(" + plugin + r",\s*[\w:]+,\s*\"[^\"]*\",(.*?)\)\s*$", text, re.S | re.M)
    if not match:
        failures.append(f"{source_file}: no SIMGATE_TRANSPORT_PLUGIN({plugin}, ...) line found")
        continue
    declared = set(re.findall(r'"(\w+)"', match.group(1)))
    in_schema = set(schema["$defs"][plugin + "_options"]["properties"])
    if declared != in_schema:
        failures.append(f"{plugin} options: plugin declares {sorted(declared)}, schema has {sorted(in_schema)}")

if failures:
    print("\n".join(failures))
    sys.exit(1)
print(f"{checked} deployments valid, {len(mistakes)} mistakes refused, {len(accepted)} near them accepted, option keys of 5 transports agree")
