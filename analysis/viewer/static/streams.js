// flocksweep viewer, part 1 of 3: the page data's streams (format flocksweep-viewer/1, documented in
// analysis/viewer/encode.py): base64 -> inflate (zlib) -> byte planes -> undo frame deltas -> dequantise.

function bytesOf(b64) {
  const bin = atob(b64);
  const out = new Uint8Array(bin.length);
  for (let i = 0; i < bin.length; i++) out[i] = bin.charCodeAt(i);
  return out;
}

async function inflate(b64) {
  const input = new Blob([bytesOf(b64)]).stream().pipeThrough(new DecompressionStream("deflate"));
  return new Uint8Array(await new Response(input).arrayBuffer());
}

export async function decode(s) {
  const raw = await inflate(s.data);
  const count = s.shape.reduce((a, b) => a * b, 1);
  if (s.dtype === "bits") {
    const out = new Uint8Array(count);
    for (let i = 0; i < count; i++) out[i] = (raw[i >> 3] >> (7 - (i & 7))) & 1;
    return out;
  }
  let q;
  if (s.dtype === "u16") {
    q = new Uint16Array(count);
    for (let i = 0; i < count; i++) q[i] = raw[i] | (raw[count + i] << 8);
  } else {
    q = raw;
  }
  if (s.delta) {
    const row = count / s.shape[0];
    for (let i = row; i < count; i++) q[i] = q[i] + q[i - row];  // typed arrays wrap like the encoder
  }
  const values = s.dtype === "i8" ? new Int8Array(q.buffer, q.byteOffset, count) : q;
  if (s.scale === undefined) return values;
  const k = s.shape[s.shape.length - 1];
  const off = Array.isArray(s.offset) ? s.offset : null, sc = Array.isArray(s.scale) ? s.scale : null;
  const out = new Float32Array(count);
  for (let i = 0; i < count; i++) {
    const c = i % k;
    out[i] = (off ? off[c] : s.offset) + (sc ? sc[c] : s.scale) * values[i];
  }
  return out;
}
