// Basis Universal textures for tests/ktx2.rs, written and read by Binomial's
// own encoder and transcoder (the WebAssembly build the npm package
// ktx2-encoder ships, pinned in package-lock.json):
//
//   node ktx2.mjs encode <in.rgba> <width> <height> <out> etc1s|uastc [basis]
//       encodes raw RGBA8 pixels (sRGB, top row first) as KTX2 with mips,
//       or as a .basis file with `basis`;
//   node ktx2.mjs transcode <in.basis> <out.rgba>
//       decodes level 0 of a .basis file to raw RGBA8 with Binomial's
//       transcoder. The wasm build has no KTX2 reader, so a test encodes the
//       same pixels both ways, with the same settings, to have a decoding of
//       the KTX2 file's blocks that is not bake's.
import { readFileSync, writeFileSync } from "node:fs";
import { encodeToKTX2 } from "ktx2-encoder";
import { NodeBasisEncoder } from "ktx2-encoder";
import { setFlagsFromString } from "node:v8";

// The tests' images are tiny: optimizing Binomial's large WebAssembly build
// would take longer than they take to encode with V8's baseline compiler.
setFlagsFromString("--liftoff-only");

const [command, ...args] = process.argv.slice(2);

if (command === "encode") {
    const [input, width, height, output, codec, container] = args;
    const pixels = new Uint8Array(readFileSync(input));
    const raw = { data: pixels, width: Number(width), height: Number(height) };
    const encoded = await encodeToKTX2(pixels, {
        isUASTC: codec === "uastc",
        isKTX2File: container !== "basis",
        generateMipmap: true,
        qualityLevel: 128,
        imageDecoder: async () => raw,
    });
    writeFileSync(output, encoded);
} else if (command === "transcode") {
    const [input, output] = args;
    const basis = await new NodeBasisEncoder().init();
    const file = new basis.BasisFile(new Uint8Array(readFileSync(input)));
    const RGBA32 = 13; // basist::transcoder_texture_format::cTFRGBA32
    if (!file.startTranscoding()) throw new Error(`${input}: the transcoder refused the file`);
    const pixels = new Uint8Array(file.getImageTranscodedSizeInBytes(0, 0, RGBA32));
    if (!file.transcodeImage(pixels, 0, 0, RGBA32, 0, 0)) throw new Error(`${input}: transcoding failed`);
    file.close();
    file.delete();
    writeFileSync(output, pixels);
} else {
    console.error("usage: ktx2.mjs encode <in.rgba> <width> <height> <out> etc1s|uastc [basis] | transcode <in.basis> <out.rgba>");
    process.exit(2);
}
