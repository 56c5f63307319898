// Read an MCAP file the way Foxglove does and print what a plot panel would get, as JSON:
// node check_mcap.mjs FILE.mcap
//
// - the file through @mcap/core's McapIndexedReader (Foxglove's MCAP reader: summary, chunk
//   indexes, CRCs) with @mcap/support's decompression handlers (zstd, lz4 as WebAssembly);
// - every "json"/"jsonschema" channel's schema through the open-source Foxglove Studio's own
//   parseJsonSchema (loaded verbatim from @foxglove/studio-base, see fetch_studio_parser.sh),
//   and each message deserialized as Studio's parseChannel does for JSON:
//   postprocessValue(JSON.parse(data));
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

const MARK = ";// CONCATENATED MODULE: ../mcap-support/src/parseJsonSchema.ts";

async function studioParseJsonSchema() {
  const file = path.join(here, "node_modules", ".foxglove-studio", "mcap-support.js");
  const text = await readFile(file, "utf8");
  const start = text.indexOf(MARK);
  if (start < 0) {
    throw new Error(`${file}: no parseJsonSchema module`);
  }
  const rest = text.slice(start + MARK.length);
  const end = rest.search(/\n(\/\/ EXTERNAL MODULE|;\/\/ CONCATENATED MODULE)/);
  const body = end < 0 ? rest : rest.slice(0, end);
  // the module's only import is @protobufjs/base64 (bound as `base64` by webpack)
  return new Function("base64", `${body}\nreturn parseJsonSchema;`)(base64);
}

function jsonable(v) {
  return JSON.parse(
    JSON.stringify(v, (_k, x) => (typeof x === "bigint" ? x.toString() : x instanceof Map ? Object.fromEntries(x) : x)),
  );
}

async function main() {
  const file = process.argv[2];
  const parseJsonSchema = await studioParseJsonSchema();
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
  const textDecoder = new TextDecoder();
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
      if (ch.messageEncoding !== "json" || schema?.encoding !== "jsonschema") {
        throw new Error(`not json/jsonschema: ${ch.messageEncoding}/${schema?.encoding}`);
      }
      const { datatypes, postprocessValue } = parseJsonSchema(
        JSON.parse(textDecoder.decode(schema.data)),
        schema.name,
      );
      t.datatypes = jsonable(datatypes);
      decoders.set(ch.id, (data) => postprocessValue(JSON.parse(textDecoder.decode(data))));
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
