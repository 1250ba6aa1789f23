#!/usr/bin/env node
// Compresses a glTF's meshes with KHR_draco_mesh_compression, or decodes
// them back to plain data, through glTF-Transform and Google's Draco
// library (npm draco3dgltf; both pinned in pipeline/package-lock.json and
// installed by pipeline/setup.sh). tests/it/draco.rs writes its compressed
// inputs with `encode` and takes `decode`'s output as the independent
// decoder that bake's own decoding must agree with.
//
//     node pipeline/draco.mjs encode IN OUT [--method edgebreaker|sequential]
//          [--position-bits N] [--normal-bits N] [--texcoord-bits N]
//          [--color-bits N] [--generic-bits N] [--speed N]
//     node pipeline/draco.mjs decode IN OUT
import { NodeIO } from '@gltf-transform/core';
import { ALL_EXTENSIONS, KHRDracoMeshCompression } from '@gltf-transform/extensions';
import draco3d from 'draco3dgltf';

const [mode, input, output, ...flags] = process.argv.slice(2);
if (!['encode', 'decode'].includes(mode) || !input || !output || flags.length % 2) {
  console.error('usage: node pipeline/draco.mjs encode|decode IN OUT [--option value ...]');
  process.exit(2);
}
const options = {};
for (let i = 0; i < flags.length; i += 2) options[flags[i].replace(/^--/, '')] = flags[i + 1];

const io = new NodeIO().registerExtensions(ALL_EXTENSIONS).registerDependencies({
  'draco3d.decoder': await draco3d.createDecoderModule(),
  'draco3d.encoder': await draco3d.createEncoderModule(),
});
const document = await io.read(input);
if (mode === 'decode') {
  for (const extension of document.getRoot().listExtensionsUsed()) {
    if (extension.extensionName === KHRDracoMeshCompression.EXTENSION_NAME) extension.dispose();
  }
} else {
  const bits = (name, fallback) => Number(options[`${name}-bits`] ?? fallback);
  const speed = Number(options.speed ?? 5);
  document
    .createExtension(KHRDracoMeshCompression)
    .setRequired(true)
    .setEncoderOptions({
      method:
        options.method === 'sequential'
          ? KHRDracoMeshCompression.EncoderMethod.SEQUENTIAL
          : KHRDracoMeshCompression.EncoderMethod.EDGEBREAKER,
      encodeSpeed: speed,
      decodeSpeed: speed,
      quantizationBits: {
        POSITION: bits('position', 14),
        NORMAL: bits('normal', 10),
        TEX_COORD: bits('texcoord', 12),
        COLOR: bits('color', 8),
        GENERIC: bits('generic', 12),
      },
    });
}
await io.write(output, document);
