// The journal tests' independent MCAP reader: opens each file with @mcap/core's indexed reader
// (summary, chunk and message indexes, chunk CRCs), reads it again with its streaming reader,
// recomputes the data section CRC, decodes CDR messages with @foxglove/rosmsg2-serialization from
// the ros2msg schema stored in the file and JSON messages with JSON.parse, and prints one JSON
// object per file on stdout (BigInt as strings, NaN as null).
// Usage: node read.js [--counts] FILE...   (--counts: per-channel totals instead of messages)
// SPDX-License-Identifier: MIT
"use strict";

const fs = require("fs");
const { McapIndexedReader, McapStreamReader } = require("@mcap/core");
const { parse } = require("@foxglove/rosmsg");
const { MessageReader } = require("@foxglove/rosmsg2-serialization");
const { crc32 } = require("@foxglove/crc");

function plain(value) {
  if (typeof value === "bigint") return value.toString();
  if (ArrayBuffer.isView(value)) return Array.from(value, plain);
  if (Array.isArray(value)) return value.map(plain);
  if (value instanceof Map) return Object.fromEntries([...value].map(([k, v]) => [k, plain(v)]));
  if (value !== null && typeof value === "object") {
    return Object.fromEntries(Object.entries(value).map(([k, v]) => [k, plain(v)]));
  }
  if (typeof value === "number" && !Number.isFinite(value)) return null;
  return value;
}

async function readFile(path, countsOnly) {
  const bytes = fs.readFileSync(path);
  const readable = {
    size: async () => BigInt(bytes.byteLength),
    read: async (offset, length) => {
      const start = Number(offset);
      return new Uint8Array(bytes.buffer, bytes.byteOffset + start, Number(length));
    },
  };
  const reader = await McapIndexedReader.Initialize({ readable });
  const out = {
    file: path,
    profile: reader.header.profile,
    library: reader.header.library,
    chunks: reader.chunkIndexes.length,
    statistics: plain(reader.statistics),
    channels: [],
    metadata: [],
  };
  const decoders = new Map();
  for (const [id, ch] of reader.channelsById) {
    const schema = reader.schemasById.get(ch.schemaId);
    const text = schema ? new TextDecoder().decode(schema.data) : "";
    out.channels.push({
      id,
      topic: ch.topic,
      message_encoding: ch.messageEncoding,
      schema_name: schema ? schema.name : "",
      schema_encoding: schema ? schema.encoding : "",
      metadata: plain(ch.metadata),
    });
    if (ch.messageEncoding === "cdr" && schema && schema.encoding === "ros2msg") {
      decoders.set(id, new MessageReader(parse(text, { ros2: true })));
    }
  }
  // The data section CRC, recomputed over [0, Data End).
  const dataEnd = Number(reader.dataEndOffset);
  out.data_section_crc = {
    stored: reader.dataSectionCrc ?? 0,
    computed: crc32(new Uint8Array(bytes.buffer, bytes.byteOffset, dataEnd)),
  };
  for await (const m of reader.readMetadata()) out.metadata.push(plain(m));

  const counts = new Map();
  const messages = [];
  let lastLogTime = -1n;
  let outOfOrder = 0;
  for await (const m of reader.readMessages()) {
    if (m.logTime < lastLogTime) outOfOrder++;
    lastLogTime = m.logTime;
    const ch = reader.channelsById.get(m.channelId);
    const decoder = decoders.get(m.channelId);
    const data = decoder ? decoder.readMessage(m.data) : JSON.parse(new TextDecoder().decode(m.data));
    const c = counts.get(m.channelId) ?? { topic: ch.topic, messages: 0, samples: 0, last_seq: null };
    c.messages++;
    if (Array.isArray(data.seq) || ArrayBuffer.isView(data.seq)) {
      c.samples += data.seq.length;
      if (data.seq.length > 0) c.last_seq = data.seq[data.seq.length - 1].toString();
    } else if (data.seq !== undefined) {
      c.samples += 1;
      c.last_seq = data.seq.toString();
    }
    counts.set(m.channelId, c);
    if (!countsOnly) {
      messages.push({
        channel: m.channelId,
        sequence: m.sequence,
        log_time: m.logTime.toString(),
        publish_time: m.publishTime.toString(),
        data: plain(data),
      });
    }
  }
  out.out_of_order = outOfOrder;
  out.counts = plain(counts);
  if (!countsOnly) out.messages = messages;

  // The streaming reader walks every record from the magic to the closing magic.
  const stream = new McapStreamReader({ validateCrcs: true });
  stream.append(new Uint8Array(bytes.buffer, bytes.byteOffset, bytes.byteLength));
  const records = {};
  for (let r; (r = stream.nextRecord()); ) records[r.type] = (records[r.type] ?? 0) + 1;
  out.stream = { records, done: stream.done() };
  return out;
}

async function main() {
  const args = process.argv.slice(2);
  const countsOnly = args[0] === "--counts";
  const files = countsOnly ? args.slice(1) : args;
  let failed = false;
  for (const f of files) {
    try {
      process.stdout.write(JSON.stringify(await readFile(f, countsOnly)) + "\n");
    } catch (e) {
      failed = true;
      process.stdout.write(JSON.stringify({ file: f, error: String(e && e.message ? e.message : e) }) + "\n");
    }
  }
  process.exitCode = failed ? 1 : 0;
}

main();
