// Interoperability check of StampScan's MCAP traces against the reference TypeScript implementation
// (@mcap/core, pinned in package.json), run by tests/acquisition/test_mcap_interop.cpp.
//
//   node mcap_interop.mjs read FILE    reads FILE with McapIndexedReader (summary, chunk and message
//                                      indexes) and with McapStreamReader (every record in order), and
//                                      prints what each found, one fact per line
//   node mcap_interop.mjs write FILE chunked|unchunked
//                                      writes a trace with @mcap/core's McapWriter (schemas and
//                                      channels inside chunks, or messages outside chunks) and prints
//                                      what it wrote, in the same format, for StampScan to read back
//
// Per channel, messages are summarised as a count and a CRC-32 chained over, in sequence order,
// each message's sequence (u32 LE), log time and publish time (u64 LE) and data.
import { McapIndexedReader, McapStreamReader, McapWriter } from "@mcap/core";
import { decompress as zstdDecompress } from "fzstd";
import { open, writeFile } from "node:fs/promises";

const CRC_TABLE = (() => {
  const table = new Uint32Array(256);
  for (let n = 0; n < 256; n++) {
    let c = n;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
    table[n] = c >>> 0;
  }
  return table;
})();

// The zlib CRC-32, continued from `crc` (0 to start), as the C++ side computes it.
function crc32(crc, bytes) {
  let c = ~crc >>> 0;
  for (let i = 0; i < bytes.length; i++) c = CRC_TABLE[(c ^ bytes[i]) & 0xff] ^ (c >>> 8);
  return ~c >>> 0;
}

function messageCrc(crc, m) {
  const head = new DataView(new ArrayBuffer(20));
  head.setUint32(0, m.sequence, true);
  head.setBigUint64(4, m.logTime, true);
  head.setBigUint64(12, m.publishTime, true);
  return crc32(crc32(crc, new Uint8Array(head.buffer)), m.data);
}

function hex(n) {
  return n.toString(16).padStart(8, "0");
}

// "<reader> channel=<id> topic=<topic> schema=<name> count=<n> crc=<hex>" per channel, id order.
function printChannels(reader, messages, channels, schemas) {
  const byChannel = new Map();
  for (const m of messages) {
    if (!byChannel.has(m.channelId)) byChannel.set(m.channelId, []);
    byChannel.get(m.channelId).push(m);
  }
  for (const id of [...byChannel.keys()].sort((a, b) => a - b)) {
    const list = byChannel.get(id).sort((a, b) => a.sequence - b.sequence);
    let crc = 0;
    for (const m of list) crc = messageCrc(crc, m);
    const channel = channels.get(id);
    const schema = channel ? schemas.get(channel.schemaId) : undefined;
    console.log(
      `${reader} channel=${id} topic=${channel?.topic ?? "?"} schema=${schema?.name ?? ""} count=${list.length} crc=${hex(crc)}`,
    );
  }
}

const decompressHandlers = {
  zstd: (buffer, size) => zstdDecompress(buffer, new Uint8Array(Number(size))),
};

async function read(path) {
  const handle = await open(path, "r");
  try {
    const size = BigInt((await handle.stat()).size);
    const readable = {
      size: async () => size,
      read: async (offset, length) => {
        const buffer = new Uint8Array(Number(length));
        await handle.read(buffer, 0, Number(length), Number(offset));
        return buffer;
      },
    };

    // Indexed: footer, summary (CRC checked), chunk indexes, message indexes.
    const indexed = await McapIndexedReader.Initialize({ readable, decompressHandlers });
    console.log(`header profile=${indexed.header.profile} library=${indexed.header.library}`);
    const st = indexed.statistics;
    console.log(
      `statistics messages=${st.messageCount} schemas=${st.schemaCount} channels=${st.channelCount} ` +
        `attachments=${st.attachmentCount} metadata=${st.metadataCount} chunks=${st.chunkCount} ` +
        `start=${st.messageStartTime} end=${st.messageEndTime}`,
    );
    console.log(`chunkindexes count=${indexed.chunkIndexes.length}`);
    const indexedMessages = [];
    for await (const m of indexed.readMessages()) indexedMessages.push(m);
    printChannels("indexed", indexedMessages, indexed.channelsById, indexed.schemasById);
    for await (const a of indexed.readAttachments())
      console.log(`attachment name=${a.name} media=${a.mediaType} size=${a.data.length} crc=${hex(crc32(0, a.data))}`);
    for await (const m of indexed.readMetadata())
      console.log(`metadata name=${m.name} keys=${[...m.metadata.entries()].map(([k, v]) => `${k}:${v}`).join(",")}`);

    // The readers do not check the data section CRC: check it here over [0, Data End).
    const dataEnd = Number(indexed.dataEndOffset);
    const data = await readable.read(0n, BigInt(dataEnd));
    const computed = crc32(0, data);
    if (indexed.dataSectionCrc == undefined) console.log("datacrc absent");
    else console.log(`datacrc ${computed === indexed.dataSectionCrc ? "ok" : "mismatch"}`);

    // Streaming: every record from the start, chunk CRCs checked.
    const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
    stream.append(await readable.read(0n, size));
    const streamMessages = [];
    const channels = new Map();
    const schemas = new Map();
    const counts = new Map();
    for (let record; (record = stream.nextRecord()); ) {
      counts.set(record.type, (counts.get(record.type) ?? 0) + 1);
      if (record.type === "Message") streamMessages.push(record);
      else if (record.type === "Channel") channels.set(record.id, record);
      else if (record.type === "Schema") schemas.set(record.id, record);
    }
    console.log(`stream done=${stream.done()} records=${[...counts.entries()].map(([k, v]) => `${k}:${v}`).sort().join(",")}`);
    printChannels("stream", streamMessages, channels, schemas);
  } finally {
    await handle.close();
  }
}

async function write(path, mode) {
  const chunks = [];
  let position = 0n;
  const writable = {
    write: async (buffer) => {
      chunks.push(buffer.slice());
      position += BigInt(buffer.byteLength);
    },
    position: () => position,
  };
  const writer = new McapWriter({ writable, useChunks: mode === "chunked", chunkSize: 2048 });
  await writer.start({ profile: "x-interop", library: "@mcap/core" });
  const schema = await writer.registerSchema({ name: "interop.Msg", encoding: "jsonschema", data: new Uint8Array([123, 125]) });
  const ids = [
    await writer.registerChannel({ schemaId: schema, topic: "/interop/a", messageEncoding: "json", metadata: new Map([["k", "v"]]) }),
    await writer.registerChannel({ schemaId: 0, topic: "/interop/b", messageEncoding: "json", metadata: new Map() }),
  ];
  const written = [];
  const sequence = [0, 0];
  for (let i = 0; i < 120; i++) {
    const c = i % 3 === 0 ? 1 : 0;
    const data = new Uint8Array(10 + ((i * 29) % 300));
    for (let k = 0; k < data.length; k++) data[k] = (i * 7 + k * 13 + (k >> 3)) & 0xff;
    const m = { channelId: ids[c], sequence: sequence[c]++, logTime: 1000n + BigInt(i) * 1000n, publishTime: 999n + BigInt(i), data };
    await writer.addMessage(m);
    written.push(m);
  }
  await writer.addMetadata({ name: "interop", metadata: new Map([["from", "typescript"]]) });
  await writer.end();
  await writeFile(path, Buffer.concat(chunks));
  const channels = new Map([
    [ids[0], { topic: "/interop/a", schemaId: schema }],
    [ids[1], { topic: "/interop/b", schemaId: 0 }],
  ]);
  printChannels("written", written, channels, new Map([[schema, { name: "interop.Msg" }]]));
}

const [command, path, mode] = process.argv.slice(2);
try {
  if (command === "read" && path) await read(path);
  else if (command === "write" && path && (mode === "chunked" || mode === "unchunked")) await write(path, mode);
  else {
    console.error("usage: node mcap_interop.mjs read FILE | write FILE chunked|unchunked");
    process.exit(2);
  }
} catch (error) {
  console.error(`mcap_interop: ${error instanceof Error ? error.message : String(error)}`);
  process.exit(1);
}
