#!/usr/bin/env python3
"""The MCAP writer's files read by a second reader nobody on the team wrote: PyPI's mcap (pure
Python), with zstandard and lz4 for the chunks (the versions tests/mcap/pypi-requirements.txt
pins). Its stream reader (every record in file order, the chunks' and the data section's CRCs
checked) and its seeking reader (the footer, the summary's schemas, channels and statistics;
messages through the chunk and message indexes, chunk CRCs checked, a window by topic and time,
in reverse; the attachment and the metadata through their indexes). One file per compression
(none, zstd, lz4), written by mcap_sample_writer (sample_writer.cc says what).

  python3 mcap_pypi_reader_test.py <mcap_sample_writer> <directory for the files>
Exit code: 0 passed, 1 failed, 77 the PyPI packages are not installed (scripts/test installs
them: scripts/lib.sh ensure_python_test_clients; ctest passes their directory in PYTHONPATH).
"""
import collections
import itertools
import os
import subprocess
import sys

try:
    import lz4.frame  # noqa: F401 (what mcap decompresses lz4 chunks with)
    import zstandard  # noqa: F401
    from mcap.reader import make_reader
    from mcap.stream_reader import StreamReader
except ImportError as e:
    print(f"SKIP: the PyPI packages are not installed (scripts/test installs them): {e}")
    sys.exit(77)

MESSAGES = 5000
TOPICS = ["/robot/pose", "/human/pose", "/simulation"]


def expected(i):
    """What the sample writer wrote as message i: its channel, log time, payload."""
    channel = i % 4
    if channel == 3:
        channel = 0
    return channel, 1_000_000_000 + i * 1_000_000, b'{"i":%d}' % i


def check(condition, what):
    if not condition:
        raise AssertionError("check failed: " + what)


def stream_read(path, kind):
    counts = collections.Counter()
    messages = []
    with open(path, "rb") as f:
        for record in StreamReader(f, validate_crcs=True).records:
            counts[type(record).__name__] += 1
            if type(record).__name__ == "Message":
                messages.append(record)
    check(len(messages) == MESSAGES, f"{kind}: {MESSAGES} messages streamed (got {len(messages)})")
    for i, m in enumerate(messages):
        channel, log_time, data = expected(i)
        check(m.channel_id == channel and m.log_time == log_time and
              m.publish_time == log_time + 1 and m.data == data, f"{kind}: message {i} as written")
    for name in ["Header", "DataEnd", "Footer", "Attachment", "Metadata", "Statistics"]:
        check(counts[name] >= 1, f"{kind}: a {name} record streamed ({dict(counts)})")
    check(counts["Schema"] == 2 * 2 and counts["Channel"] == 2 * 3,
          f"{kind}: the schemas and channels, in the data section and the summary ({dict(counts)})")
    check(counts["ChunkIndex"] > 5 and counts["MessageIndex"] >= counts["ChunkIndex"],
          f"{kind}: many chunks, each indexed, each with its message indexes ({dict(counts)})")


def seeking_read(path, kind):
    with open(path, "rb") as f:
        reader = make_reader(f, validate_crcs=True, decoder_factories=[])
        check(type(reader).__name__ == "SeekingReader", f"{kind}: a seeking reader ({reader})")
        check(reader.get_header().library == "simgate", f"{kind}: the header's library")
        summary = reader.get_summary()
        check(summary is not None, f"{kind}: a summary")
        check(sorted((s.id, s.name, s.encoding) for s in summary.schemas.values()) ==
              [(1, "simgate.pose", "jsonschema"), (2, "simgate.other", "jsonschema")],
              f"{kind}: the schemas")
        channels = summary.channels
        check([channels[i].topic for i in sorted(channels)] == TOPICS,
              f"{kind}: the channels' topics")
        check(channels[0].metadata == {"component": "robot.pose"}, f"{kind}: a channel's metadata")
        stats = summary.statistics
        check(stats.message_count == MESSAGES and
              stats.channel_message_counts == {0: 2500, 1: 1250, 2: 1250},
              f"{kind}: the statistics' message counts ({stats})")
        check(stats.message_start_time == expected(0)[1] and
              stats.message_end_time == expected(MESSAGES - 1)[1], f"{kind}: the first and last log times")
        check(stats.chunk_count == len(summary.chunk_indexes) and stats.attachment_count == 1 and
              stats.metadata_count == 1, f"{kind}: chunk, attachment and metadata counts")
        check(all(c.compression == ("" if kind == "none" else kind) for c in summary.chunk_indexes),
              f"{kind}: the chunks' compression")

        # every message, in log time order, through the indexes
        n = 0
        for schema, channel, message in reader.iter_messages():
            channel_id, log_time, data = expected(n)
            check(channel.id == channel_id and channel.topic == TOPICS[channel_id] and
                  schema.id == (2 if channel_id == 2 else 1) and message.log_time == log_time and
                  message.data == data, f"{kind}: indexed message {n}")
            n += 1
        check(n == MESSAGES, f"{kind}: every message through the indexes ({n})")
        # a window on one topic, and the last messages in reverse
        window = list(reader.iter_messages(topics=["/simulation"], starting_at=expected(4000)[1],
                                           ending_before=expected(4100)[1]))
        check(len(window) == 25 and all(c.topic == "/simulation" for _, c, _ in window),
              f"{kind}: a seek by time and topic ({len(window)} messages)")
        last = [m.data for _, _, m in itertools.islice(reader.iter_messages(reverse=True), 3)]
        check(last == [expected(i)[2] for i in (4999, 4998, 4997)], f"{kind}: in reverse ({last})")

        attachments = list(reader.iter_attachments())
        check(len(attachments) == 1 and attachments[0].name == "config.json" and
              attachments[0].media_type == "application/json" and
              attachments[0].data == b'{"scene": "demo.xml"}' and attachments[0].create_time == 7,
              f"{kind}: the attachment")
        metadata = list(reader.iter_metadata())
        check(len(metadata) == 1 and metadata[0].name == "simgate" and
              metadata[0].metadata == {"version": "0.1.0", "mujoco": "4.0.0"}, f"{kind}: the metadata")


def main(writer, directory):
    import mcap
    print(f"mcap {getattr(mcap, '__version__', '?')}, zstandard {zstandard.__version__}, "
          f"lz4 {lz4.__version__} (Python {sys.version.split()[0]})")
    for kind in ["none", "zstd", "lz4"]:
        # (names of its own: McapReader.FilesReadByMcapCore writes sample-*.mcap beside them)
        path = os.path.join(directory, f"pypi-sample-{kind}.mcap")
        subprocess.run([writer, path, kind], check=True, stdout=subprocess.DEVNULL)
        stream_read(path, kind)
        seeking_read(path, kind)
        print(f"{kind}: {os.path.getsize(path)} bytes, read back by PyPI's mcap")
    print("PASS: MCAP files read by PyPI's mcap (stream with CRCs, seeking through the indexes)")
    return 0


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: mcap_pypi_reader_test.py <mcap_sample_writer> <directory for the files>")
    try:
        sys.exit(main(*sys.argv[1:]))
    except Exception as e:  # noqa: BLE001 (any failure is the test's)
        import traceback
        traceback.print_exc()
        print(f"FAIL: {e}")
        sys.exit(1)
