"""A rollout log and its Foxglove view read with the official `mcap` Python reader and
`google.protobuf`, the way Foxglove and other standard tools read them: a summary section,
every channel in an encoding those tools know, every message decoded with the descriptors
stored in the file, and what the decoded messages say agrees with `smirl.read_log`."""

import json
import subprocess
import sys
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap.reader import make_reader

import smirl
from conftest import ROOT, scripted_demo_log

# The workplace's shared log checker, beside the checkout (absent on a machine without it).
SHARED_CHECKER = ROOT.parent / "shared" / "tools" / "check_mcap.py"

# (schema encoding, message encoding) pairs Foxglove decodes.
FOXGLOVE_ENCODINGS = {
    ("protobuf", "protobuf"),
    ("jsonschema", "json"),
    ("", "json"),
    ("ros1msg", "ros1"),
    ("ros2msg", "cdr"),
    ("ros2idl", "cdr"),
    ("flatbuffer", "flatbuffer"),
}


def read_with_the_official_reader(path):
    """Every message of the file decoded: a list of (topic, schema name, decoded message)."""
    decoders, messages = {}, []
    with open(path, "rb") as f:
        reader = make_reader(f)
        summary = reader.get_summary()
        assert summary is not None, f"{path}: no summary section"
        for channel in summary.channels.values():
            schema = summary.schemas.get(channel.schema_id)
            pair = (schema.encoding if schema else "", channel.message_encoding)
            assert pair in FOXGLOVE_ENCODINGS, f"{channel.topic} is encoded as {pair}"
        for schema, channel, message in reader.iter_messages():
            if channel.message_encoding == "protobuf":
                if schema.id not in decoders:
                    pool = descriptor_pool.DescriptorPool()
                    for fd in descriptor_pb2.FileDescriptorSet.FromString(schema.data).file:
                        pool.Add(fd)
                    desc = pool.FindMessageTypeByName(schema.name)
                    decoders[schema.id] = message_factory.GetMessageClass(desc)
                decoded = decoders[schema.id].FromString(message.data)
            else:
                decoded = json.loads(message.data)
            messages.append((channel.topic, schema.name if schema else "", decoded))
        assert summary.statistics.message_count == len(messages)
    return messages


@pytest.fixture(scope="module")
def cancel_log(tmp_path_factory, reacher_bin):
    """Scripted IF demonstrations with observations, written by the `reacher` binary."""
    return scripted_demo_log(reacher_bin, tmp_path_factory.mktemp("official") / "if.mcap", "if", 4)


@pytest.fixture(scope="module")
def foxglove_view(cancel_log, reacher_bin):
    """`reacher foxglove`'s view of `cancel_log`, beside it."""
    view = cancel_log.with_name("view.mcap")
    out = subprocess.run([reacher_bin, "foxglove", str(cancel_log), "--out", str(view)], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
    return view


def test_the_official_reader_decodes_the_log_as_smirl_reads_it(cancel_log):
    messages = read_with_the_official_reader(cancel_log)
    log = smirl.read_log(cancel_log)
    steps = [m for topic, _, m in messages if topic == "/step"]
    assert len(steps) == sum(len(ep["actions"]) for ep in log["episodes"])
    for msg in steps:
        ep = log["episodes"][msg.episode]
        # Steps count from 1 (the state after the first action).
        np.testing.assert_array_equal(np.array(msg.qpos), ep["qpos"][msg.step - 1])
        np.testing.assert_array_equal(np.array(msg.action, np.float32), ep["actions"][msg.step - 1])
        assert msg.rm_state == ep["rm_states"][msg.step - 1]


def test_the_official_reader_decodes_the_foxglove_view(cancel_log, foxglove_view):
    messages = read_with_the_official_reader(foxglove_view)
    by_schema = Counter(schema for _, schema, _ in messages)
    log = smirl.read_log(cancel_log)
    states = sum(len(ep["actions"]) + 1 for ep in log["episodes"])
    assert by_schema["foxglove.SceneUpdate"] == states, by_schema
    assert by_schema["foxglove.FrameTransforms"] == states, by_schema
    # The view keeps the log: its steps are the log's steps.
    assert by_schema["smirl.v1.Step"] == sum(len(ep["actions"]) for ep in log["episodes"])
    scene = next(m for _, schema, m in messages if schema == "foxglove.SceneUpdate")
    assert scene.entities and any(e.spheres for e in scene.entities)


def test_the_shared_checker_accepts_the_log_and_the_view(cancel_log, foxglove_view):
    if not SHARED_CHECKER.exists():
        pytest.skip(f"{SHARED_CHECKER} is not on this machine")
    for path in (cancel_log, foxglove_view):
        out = subprocess.run([sys.executable, str(SHARED_CHECKER), str(path)], capture_output=True, text=True)
        assert out.returncode == 0, out.stdout + out.stderr


def test_the_decode_script_prints_what_smirl_reads(cancel_log):
    """`experiments/mcap/decode_protobuf.py` prints step 42 of every episode that has one, as
    protobuf decodes it."""
    script = ROOT / "experiments" / "mcap" / "decode_protobuf.py"
    out = subprocess.run([sys.executable, str(script), str(cancel_log)], capture_output=True, text=True)
    assert out.returncode == 0, out.stdout + out.stderr
    log = smirl.read_log(cancel_log)
    printed = {}
    for line in out.stdout.splitlines():
        if line.startswith("episode "):
            head, rest = line.split(": ", 1)
            printed[int(head.split()[1])] = dict(f.split("=", 1) for f in rest.split(" ") if "=" in f)
    long_enough = [i for i, ep in enumerate(log["episodes"]) if len(ep["actions"]) >= 42]
    assert long_enough and sorted(printed) == long_enough, out.stdout
    for i, fields in printed.items():
        ep = log["episodes"][i]
        # Steps count from 1: step 42 is row 41.
        assert float(fields["qpos0"]) == ep["qpos"][41][0], fields
        assert int(fields["labels"]) == ep["labels"][41], fields
        assert int(fields["rm_state"]) == ep["rm_states"][41], fields
