#!/usr/bin/env node
// Reference decode of a Basis Universal KTX2 (ETC1S or UASTC) to an RGBA8 PNG, level 0, with the upstream C++
// transcoder compiled to wasm (BASIS_TRANSCODER_DIR holds basis_transcoder.js and .wasm). Usage: IN.ktx2 OUT.png
const fs = require('fs'), path = require('path'), zlib = require('zlib');
const dir = process.env.BASIS_TRANSCODER_DIR;
// three's package.json declares "type": "module", so the emscripten glue (CommonJS) is compiled as a module by hand.
const glue = path.join(dir, 'basis_transcoder.js');
const BASIS = (() => {
  const m = new module.constructor(glue, module);
  m.filename = glue;
  m.paths = module.paths;
  m._compile(fs.readFileSync(glue, 'utf8'), glue);
  return m.exports;
})();

function png(w, h, rgba) {
  const table = new Int32Array(256).map((_, n) => {
    let c = n;
    for (let k = 0; k < 8; k++) c = c & 1 ? 0xedb88320 ^ (c >>> 1) : c >>> 1;
    return c;
  });
  const crc = (b) => { let c = -1; for (const x of b) c = table[(c ^ x) & 255] ^ (c >>> 8); return (c ^ -1) >>> 0; };
  const chunk = (type, data) => {
    const len = Buffer.alloc(4); len.writeUInt32BE(data.length);
    const body = Buffer.concat([Buffer.from(type), data]);
    const sum = Buffer.alloc(4); sum.writeUInt32BE(crc(body));
    return Buffer.concat([len, body, sum]);
  };
  const ihdr = Buffer.alloc(13); ihdr.writeUInt32BE(w, 0); ihdr.writeUInt32BE(h, 4); ihdr.set([8, 6, 0, 0, 0], 8);
  const raw = Buffer.alloc((w * 4 + 1) * h);
  for (let y = 0; y < h; y++) Buffer.from(rgba.buffer, rgba.byteOffset + y * w * 4, w * 4).copy(raw, y * (w * 4 + 1) + 1);
  return Buffer.concat([Buffer.from([137, 80, 78, 71, 13, 10, 26, 10]), chunk('IHDR', ihdr),
    chunk('IDAT', zlib.deflateSync(raw)), chunk('IEND', Buffer.alloc(0))]);
}

(async () => {
  const [input, output] = process.argv.slice(2);
  const M = await BASIS({ wasmBinary: fs.readFileSync(path.join(dir, 'basis_transcoder.wasm')) });
  M.initializeBasis();
  const f = new M.KTX2File(new Uint8Array(fs.readFileSync(input)));
  if (!f.isValid() || !f.startTranscoding()) throw new Error(`${input}: not a transcodable KTX2`);
  const rgba32 = M.transcoder_texture_format.cTFRGBA32.value;
  const texels = new Uint8Array(f.getImageTranscodedSizeInBytes(0, 0, 0, rgba32));
  if (!f.transcodeImage(texels, 0, 0, 0, rgba32, 0, -1, -1)) throw new Error(`${input}: transcoding failed`);
  fs.writeFileSync(output, png(f.getWidth(), f.getHeight(), texels));
  f.close(); f.delete();
})().catch((e) => { console.error(e); process.exit(1); });
