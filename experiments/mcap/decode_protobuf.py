#!/usr/bin/env python3
"""Decode a smirl rollout log's protobuf channels with the descriptors stored in the file
(google.protobuf + the official mcap reader), as Foxglove does. Checks every message decodes
and prints a summary plus one sample step per episode.

usage: decode_protobuf.py FILE.mcap      (pip install mcap protobuf)
"""
import sys

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
from mcap.reader import make_reader


def main(path):
    classes = {}
    counts = {}
    with open(path, "rb") as f:
        for schema, channel, message in make_reader(f).iter_messages():
            if channel.message_encoding != "protobuf":
                continue
            if schema.id not in classes:
                fds = descriptor_pb2.FileDescriptorSet.FromString(schema.data)
                pool = descriptor_pool.DescriptorPool()
                for fd in fds.file:
                    pool.Add(fd)
                desc = pool.FindMessageTypeByName(schema.name)
                classes[schema.id] = message_factory.GetMessageClass(desc)
            msg = classes[schema.id].FromString(message.data)
            counts[schema.name] = counts.get(schema.name, 0) + 1
            if schema.name == "smirl.v1.Step" and msg.step == 42:
                print(f"episode {msg.episode} step {msg.step}: qpos0={msg.qpos[0]!r} "
                      f"labels={msg.labels} action={list(msg.action)} rm_state={msg.rm_state}")
    print(", ".join(f"{k}={v}" for k, v in sorted(counts.items())))
    return 0 if counts else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
