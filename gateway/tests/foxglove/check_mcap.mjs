// Read an MCAP file the way Foxglove does and print what a plot panel would get, as JSON:
// node check_mcap.mjs FILE.mcap
//
// - the file through @mcap/core's McapIndexedReader (Foxglove's MCAP reader: summary, chunk
//   indexes, CRCs) with @mcap/support's decompression handlers (zstd, lz4 as WebAssembly);
// - every channel through the open-source Foxglove Studio's own parseChannel (loaded verbatim
//   from @foxglove/studio-base, see fetch_studio_parser.sh, with the modules it uses for JSON
//   and protobuf: parseJsonSchema, protobufDefinitionsToDatatypes; protobufjs and its
//   descriptor extension from npm, as Studio bundles them): its datatypes, and each message
//   deserialized by the function it returns;
// - for every topic: the datatypes, or the parser's error; the messages' count and first one;
//   the (log time, field) series of numeric top-level fields a plot panel would draw;
// - @foxglove/schemas' own foxglove.Log JSON schema, to compare with the one the file holds.
import { readFile } from "node:fs/promises";
import { createRequire } from "node:module";
import { fileURLToPath } from "node:url";
import path from "node:path";

import { McapIndexedReader } from "@mcap/core";
import { loadDecompressHandlers } from "@mcap/support";

const require = createRequire(import.meta.url);
const base64 = require("@protobufjs/base64");
const foxgloveJsonSchemas = require("@foxglove/schemas/jsonschema");
const here = path.dirname(fileURLToPath(import.meta.url));

const MODULES = ["parseJsonSchema", "protobufDefinitionsToDatatypes", "parseChannel"];

function moduleBody(text, name, file) {
  const mark = `;// CONCATENATED MODULE: ../mcap-support/src/${name}.ts`;
  const start = text.indexOf(mark);
  if (start < 0) {
    throw new Error(`${file}: no ${name} module`);
  }
  const rest = text.slice(start + mark.length);
  const end = rest.search(/\n(\/\/ EXTERNAL MODULE|;\/\/ CONCATENATED MODULE)/);
  return end < 0 ? rest : rest.slice(0, end);
}

async function studioParseChannel() {
  const file = path.join(here, "node_modules", ".foxglove-studio", "mcap-support.js");
  const text = await readFile(file, "utf8");
  const body = MODULES.map((m) => moduleBody(text, m, file)).join("\n");
  // the bindings webpack gives these modules; ROS and flatbuffer readers are not needed here
  const unused = (what) => () => {
    throw new Error(`${what} is not loaded by check_mcap`);
  };
  const protobufjs = require("protobufjs");
  const descriptor = require("protobufjs/ext/descriptor");
  return new Function(
    "base64",
    "protobufjs_default",
    "descriptor",
    "dist",
    "esm",
    "rosmsg2_serialization_dist",
    "parseFlatbufferSchema",
    `${body}\nreturn parseChannel;`,
  )(base64, () => protobufjs, descriptor, { parse: unused("rosmsg") }, {}, {}, unused("flatbuffers"));
}

function jsonable(v) {
  return JSON.parse(
    JSON.stringify(v, (_k, x) => (typeof x === "bigint" ? x.toString() : x instanceof Map ? Object.fromEntries(x) : x)),
  );
}

async function main() {
  const file = process.argv[2];
  const parseChannel = await studioParseChannel();
  const buf = await readFile(file);
  const readable = {
    size: async () => BigInt(buf.byteLength),
    read: async (offset, length) => buf.subarray(Number(offset), Number(offset + length)),
  };
  const reader = await McapIndexedReader.Initialize({
    readable,
    decompressHandlers: await loadDecompressHandlers(),
  });
  const topics = {};
  const decoders = new Map();
  for (const ch of reader.channelsById.values()) {
    const schema = reader.schemasById.get(ch.schemaId);
    const t = (topics[ch.topic] = {
      messageEncoding: ch.messageEncoding,
      schemaName: schema?.name,
      schemaEncoding: schema?.encoding,
      count: 0,
      series: {},
    });
    try {
      const { datatypes, deserialize } = parseChannel({
        messageEncoding: ch.messageEncoding,
        schema: schema == undefined ? undefined : { name: schema.name, encoding: schema.encoding, data: schema.data },
      });
      t.datatypes = jsonable(datatypes);
      decoders.set(ch.id, deserialize);
    } catch (err) {
      t.error = String(err.message ?? err);
    }
  }
  for await (const m of reader.readMessages()) {
    const ch = reader.channelsById.get(m.channelId);
    const t = topics[ch.topic];
    t.count += 1;
    const decode = decoders.get(m.channelId);
    if (decode == undefined) {
      continue;
    }
    const msg = decode(m.data);
    if (t.count === 1) {
      t.first = jsonable(msg);
    }
    for (const [k, v] of Object.entries(msg)) {
      if (typeof v === "number") {
        (t.series[k] ??= []).push([m.logTime.toString(), m.publishTime.toString(), v]);
      }
    }
  }
  process.stdout.write(
    JSON.stringify({
      profile: reader.header.profile,
      library: reader.header.library,
      topics,
      foxgloveLogSchema: foxgloveJsonSchemas.Log,
    }),
  );
}

main().catch((err) => {
  process.stderr.write(`check_mcap: ${err.stack ?? err}\n`);
  process.exit(1);
});
