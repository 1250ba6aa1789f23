#!/usr/bin/env node
// Runs the Khronos glTF validator (npm package gltf-validator, pinned in
// pipeline/package-lock.json and installed by pipeline/setup.sh) on one .glb
// or .gltf file and prints its report as JSON on stdout. A .gltf's external
// buffers and images are read from beside it.
//
//     node pipeline/validate.mjs baked/scene.glb
//
// Exit code: 0 when the file has no errors (warnings and infos allowed),
// 1 when it has errors, 2 when it could not be validated at all.
import { readFile } from 'node:fs/promises';
import path from 'node:path';

const file = process.argv[2];
if (!file || process.argv.length > 3) {
  console.error('usage: node pipeline/validate.mjs FILE.glb|FILE.gltf');
  process.exit(2);
}

let validator;
try {
  validator = (await import('gltf-validator')).default;
} catch (error) {
  console.error(`validate.mjs: the glTF validator is not installed (${error.code ?? error}); run ./pipeline/setup.sh`);
  process.exit(2);
}

try {
  const bytes = new Uint8Array(await readFile(file));
  const report = await validator.validateBytes(bytes, {
    uri: path.basename(file),
    maxIssues: 0, // report every issue
    externalResourceFunction: async (uri) =>
      new Uint8Array(await readFile(path.resolve(path.dirname(file), decodeURIComponent(uri)))),
  });
  console.log(JSON.stringify(report, null, 2));
  // Not process.exit(): it would cut a report longer than a pipe's buffer
  // (64 KiB) short, since Node writes to a pipe asynchronously.
  process.exitCode = report.issues.numErrors > 0 ? 1 : 0;
} catch (error) {
  console.error(`validate.mjs: ${file}: ${error}`);
  process.exitCode = 2;
}
