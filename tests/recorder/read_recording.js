#!/usr/bin/env node
// A recording read by @mcap/core's indexed reader (a reader nobody on the team wrote), every
// CRC checked, zstd chunks decompressed by @mcap/support: prints {"topics": {topic: messages},
// "schemas": [names], "attachments": [names], "metadata": [names], "statistics": {...}} as one
// JSON line for recording_test.py to check.
//   node read_recording.js FILE.mcap
// Exit code: 0 read, 1 not readable, 77 the npm packages are not installed (tests/mcap).
'use strict';

const fs = require('fs');
const path = require('path');

let McapIndexedReader, loadDecompressHandlers;
try {
  const modules = path.join(__dirname, '..', 'mcap', 'node_modules');
  ({ McapIndexedReader } = require(path.join(modules, '@mcap', 'core')));
  ({ loadDecompressHandlers } = require(path.join(modules, '@mcap', 'support')));
} catch (e) {
  console.log('SKIP: the npm packages are not installed (npm install in tests/mcap): ' + e.message);
  process.exit(77);
}

async function main() {
  const bytes = fs.readFileSync(process.argv[2]);
  const readable = {
    size: async () => BigInt(bytes.length),
    read: async (offset, length) => bytes.subarray(Number(offset), Number(offset + length)),
  };
  const reader = await McapIndexedReader.Initialize({
    readable, decompressHandlers: await loadDecompressHandlers(),
  });
  const topics = {};
  for await (const m of reader.readMessages({ validateCrcs: true })) {
    const topic = reader.channelsById.get(m.channelId).topic;
    topics[topic] = (topics[topic] || 0) + 1;
  }
  const attachments = [];
  for await (const a of reader.readAttachments()) attachments.push(a.name);
  const metadata = [];
  for await (const m of reader.readMetadata()) metadata.push(m.name);
  const s = reader.statistics;
  console.log(JSON.stringify({
    topics,
    schemas: [...reader.schemasById.values()].map((x) => x.name),
    attachments, metadata,
    statistics: { messages: Number(s.messageCount), chunks: s.chunkCount, channels: s.channelCount },
  }));
}

main().catch((e) => {
  console.error('FAILED: ' + (e.stack || e));
  process.exit(1);
});
