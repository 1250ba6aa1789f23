#!/usr/bin/env node
// Validates JSON files against a JSON Schema (draft 2020-12) with Ajv (npm
// package ajv, pinned in pipeline/package-lock.json and installed by
// pipeline/setup.sh). tests/it/report.rs checks bake's report.json with it.
//
//     node pipeline/schema.mjs schema/report.schema.json out/report.json ...
//
// Prints {"FILE": ["message at /instance/path", ...], ...} on stdout, an
// empty list for a file that follows the schema. Exit code: 0 when every file
// could be checked (valid or not), 2 when the schema itself is not valid
// draft 2020-12 or a file could not be read.
import { readFile } from 'node:fs/promises';

const [schemaFile, ...files] = process.argv.slice(2);
if (!schemaFile || files.length === 0) {
  console.error('usage: node pipeline/schema.mjs SCHEMA.json FILE.json...');
  process.exit(2);
}

let Ajv2020;
try {
  Ajv2020 = (await import('ajv/dist/2020.js')).default;
} catch (error) {
  console.error(`schema.mjs: ajv is not installed (${error.code ?? error}); run ./pipeline/setup.sh`);
  process.exit(2);
}

const readJson = async (file) => JSON.parse(await readFile(file, 'utf8'));
try {
  // An unknown keyword or format in the schema is an error, not ignored; a
  // keyword without the type it applies to is fine (draft 2020-12 allows it).
  const ajv = new Ajv2020({ allErrors: true, strict: true, strictTypes: false });
  const schema = await readJson(schemaFile);
  if (!ajv.validateSchema(schema)) {
    console.error(`schema.mjs: ${schemaFile} is not valid draft 2020-12: ${ajv.errorsText(ajv.errors)}`);
    process.exit(2);
  }
  const validate = ajv.compile(schema);
  const found = {};
  for (const file of files) {
    validate(await readJson(file));
    found[file] = (validate.errors ?? []).map((e) => `${e.message} at ${e.instancePath || '/'}`);
  }
  console.log(JSON.stringify(found, null, 2));
} catch (error) {
  console.error(`schema.mjs: ${error.message ?? error}`);
  process.exit(2);
}
