// The reference for avsim's PyTorch port of the @vladmandic/human CenterNet graph:
// runs centernet.json/.bin with the TF.js runtime itself (tfjs-core + tfjs-converter on the
// pure-JS CPU backend, no native build) on raw inputs, and writes what the graph returns.
//
//   node reference.js JOB.json
//
// JOB.json: {
//   "model_json": ".../centernet.json", "model_bin": ".../centernet.bin",
//   "inputs": [{"path": "frame.f32", "height": 480, "width": 640, "resize_to": 512}],
//   "dump_maps": false,           // also write tower_0/keypoints and tower_0/wh as PATH.keypoints.f32 / .wh.f32
//   "out": "detections.json"
// }
// Each input is a raw little-endian float32 file holding a 1 x height x width x 3 RGB tensor,
// values 0-255. With "resize_to": N it is first resized to N x N with tf.image.resizeBilinear and
// its defaults (no corner alignment, no half-pixel centres), as human's src/object/centernet.ts
// feeds the model; without it, the tensor goes to the graph as it is.
// The output JSON holds, per input, the graph's tower_0/detections [100][6] (x1, y1, x2, y2 in
// model-input pixels, score, class) and the versions that made it.
'use strict';

const fs = require('fs');
const { loadGraph, tf } = require('./graph_model');

function readInput(spec) {
  const bytes = fs.readFileSync(spec.path);
  const expected = spec.height * spec.width * 3 * 4;
  if (bytes.byteLength !== expected) {
    throw new Error(`${spec.path}: ${bytes.byteLength} bytes, expected ${expected} for 1x${spec.height}x${spec.width}x3 float32`);
  }
  const values = new Float32Array(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength));
  return tf.tensor4d(values, [1, spec.height, spec.width, 3], 'float32');
}

async function main() {
  const job = JSON.parse(fs.readFileSync(process.argv[2], 'utf8'));
  const model = await loadGraph(job.model_json, job.model_bin);
  const names = job.dump_maps ? ['tower_0/detections', 'tower_0/keypoints', 'tower_0/wh'] : ['tower_0/detections'];
  const results = [];
  for (const spec of job.inputs) {
    const raw = readInput(spec);
    const input = spec.resize_to ? tf.image.resizeBilinear(raw, [spec.resize_to, spec.resize_to]) : raw;
    const outputs = [].concat(model.execute(input, names));
    results.push({ path: spec.path, detections: (await outputs[0].array())[0] });
    if (job.dump_maps) {
      fs.writeFileSync(`${spec.path}.keypoints.f32`, Buffer.from((await outputs[1].data()).buffer));
      fs.writeFileSync(`${spec.path}.wh.f32`, Buffer.from((await outputs[2].data()).buffer));
    }
    tf.dispose([raw, input, ...outputs]);
  }
  const versions = { 'tfjs-core': tf.version_core, 'tfjs-converter': require('@tensorflow/tfjs-converter').version_converter, backend: tf.getBackend(), node: process.version };
  fs.writeFileSync(job.out, JSON.stringify({ versions, results }));
}

main().catch((err) => {
  console.error(`reference.js: ${err.message}`);
  process.exit(1);
});
