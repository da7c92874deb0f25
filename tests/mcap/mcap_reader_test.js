#!/usr/bin/env node
// The MCAP writer's files read by readers nobody on the team wrote: @mcap/core's stream
// reader (every record in order, every CRC checked: chunks, attachments, data section,
// summary) and its indexed reader (the footer, the summary's schemas, channels, chunk indexes
// and statistics; messages sought by time through the chunk and message indexes; attachments
// and metadata through theirs), with @mcap/support's zstd and lz4 decompressors. One file per
// compression (none, zstd, lz4), written by mcap_sample_writer (sample_writer.cc says what).
//
//   node mcap_reader_test.js <mcap_sample_writer> <directory for the files>
// Exit code: 0 passed, 1 failed, 77 the npm packages are not installed.
'use strict';

const fs = require('fs');
const path = require('path');
const { execFileSync } = require('child_process');

let McapStreamReader, McapIndexedReader, loadDecompressHandlers;
try {
  ({ McapStreamReader, McapIndexedReader } = require(path.join(__dirname, 'node_modules', '@mcap', 'core')));
  ({ loadDecompressHandlers } = require(path.join(__dirname, 'node_modules', '@mcap', 'support')));
} catch (e) {
  console.log('SKIP: the npm packages are not installed (npm install in tests/mcap): ' + e.message);
  process.exit(77);
}

const MESSAGES = 5000;

function check(condition, what) {
  if (!condition) throw new Error('check failed: ' + what);
}

// What the sample writer wrote as message i: its channel, log time, payload.
function expected(i) {
  let c = i % 4;
  if (c === 3) c = 0;
  return { channel: c, logTime: 1000000000n + BigInt(i) * 1000000n, data: `{"i":${i}}` };
}

function streamRead(bytes, decompressHandlers, kind) {
  const reader = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  reader.append(bytes);
  const counts = {};
  const messages = [];
  for (let record; (record = reader.nextRecord());) {
    counts[record.type] = (counts[record.type] || 0) + 1;
    if (record.type === 'Message') messages.push(record);
  }
  check(reader.done(), `${kind}: the stream reader reached the end (the footer and the magic)`);
  check(messages.length === MESSAGES, `${kind}: ${MESSAGES} messages streamed (got ${messages.length})`);
  messages.forEach((m, i) => {
    const e = expected(i);
    check(m.channelId === e.channel && m.logTime === e.logTime && m.publishTime === e.logTime + 1n &&
          Buffer.from(m.data).toString() === e.data, `${kind}: message ${i} as written`);
  });
  for (const type of ['Header', 'DataEnd', 'Footer', 'Attachment', 'Metadata', 'Statistics'])
    check(counts[type] >= 1, `${kind}: a ${type} record streamed (${JSON.stringify(counts)})`);
  check(counts.ChunkIndex > 5 && counts.MessageIndex >= counts.ChunkIndex,
        `${kind}: many chunks, each indexed, each with its message indexes (${JSON.stringify(counts)})`);
  return counts;
}

async function indexedRead(bytes, decompressHandlers, kind) {
  const readable = {
    size: async () => BigInt(bytes.length),
    read: async (offset, size) => bytes.subarray(Number(offset), Number(offset + size)),
  };
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
  check(reader.header.library === 'simgate', `${kind}: the header's library`);
  check(reader.schemasById.size === 2 && reader.schemasById.get(1).name === 'simgate.pose' &&
        reader.schemasById.get(2).encoding === 'jsonschema', `${kind}: the schemas`);
  const topics = [...reader.channelsById.values()].map((c) => c.topic);
  check(JSON.stringify(topics) === '["/robot/pose","/human/pose","/simulation"]', `${kind}: the channels: ${topics}`);
  check(reader.channelsById.get(0).metadata.get('component') === 'robot.pose', `${kind}: a channel's metadata`);
  const s = reader.statistics;
  check(s && s.messageCount === BigInt(MESSAGES), `${kind}: statistics count the messages`);
  check(s.channelMessageCounts.get(0) === 2500n && s.channelMessageCounts.get(1) === 1250n &&
        s.channelMessageCounts.get(2) === 1250n, `${kind}: messages per channel`);
  check(s.messageStartTime === expected(0).logTime && s.messageEndTime === expected(MESSAGES - 1).logTime,
        `${kind}: the first and last log times`);
  check(s.chunkCount === reader.chunkIndexes.length && s.attachmentCount === 1 && s.metadataCount === 1,
        `${kind}: chunk, attachment and metadata counts`);
  check(reader.chunkIndexes.every((c) => c.compression === (kind === 'none' ? '' : kind)), `${kind}: the chunks' compression`);

  // all of it, in time order, through the indexes
  let n = 0;
  for await (const m of reader.readMessages()) {
    const e = expected(n++);
    check(m.logTime === e.logTime && Buffer.from(m.data).toString() === e.data, `${kind}: indexed message ${n - 1}`);
  }
  check(n === MESSAGES, `${kind}: every message through the indexes (${n})`);
  // a time window on one topic: only what the indexes say is there
  const from = expected(4000).logTime, to = expected(4099).logTime;
  const window = [];
  for await (const m of reader.readMessages({ topics: ['/simulation'], startTime: from, endTime: to }))
    window.push(m);
  check(window.length === 25 && window.every((m) => m.channelId === 2 && m.logTime >= from && m.logTime <= to),
        `${kind}: a seek by time and topic (${window.length} messages)`);
  const attachments = [];
  for await (const a of reader.readAttachments()) attachments.push(a);
  check(attachments.length === 1 && attachments[0].name === 'config.json' && attachments[0].mediaType === 'application/json' &&
        Buffer.from(attachments[0].data).toString() === '{"scene": "demo.xml"}' && attachments[0].createTime === 7n,
        `${kind}: the attachment`);
  const metadata = [];
  for await (const m of reader.readMetadata()) metadata.push(m);
  check(metadata.length === 1 && metadata[0].name === 'simgate' && metadata[0].metadata.get('mujoco') === '4.0.0',
        `${kind}: the metadata`);
}

async function main([writer, directory]) {
  const decompressHandlers = await loadDecompressHandlers();
  for (const kind of ['none', 'zstd', 'lz4']) {
    const file = path.join(directory, `sample-${kind}.mcap`);
    execFileSync(writer, [file, kind]);
    const bytes = new Uint8Array(fs.readFileSync(file));
    streamRead(bytes, decompressHandlers, kind);
    await indexedRead(bytes, decompressHandlers, kind);
    console.log(`${kind}: ${bytes.length} bytes, read back by @mcap/core`);
  }
  console.log('PASS: MCAP files read by @mcap/core (stream with CRCs, indexed with seeks)');
}

main(process.argv.slice(2)).catch((e) => {
  console.error('FAIL: ' + (e && e.stack ? e.stack : e));
  process.exit(1);
});
