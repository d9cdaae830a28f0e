// Runs any TF.js graph model on one raw float32 input and writes the outputs it is asked for, as the
// reference for avsim's graph interpreters (NanoDet: tests/perception/nanodet/test_nanodet_reference.py).
//
//   node graph_outputs.js JOB.json
//
// JOB.json: {"model_json": ".../nanodet.json", "model_bin": ".../nanodet.bin",
//            "input": {"path": "x.f32", "shape": [1, 3, 416, 416]},
//            "outputs": ["Identity", "Identity_3"], "out_prefix": "/tmp/ref"}
// The input file holds the tensor as little-endian float32, row-major in `shape`. Each output goes to
// OUT_PREFIX.NAME.f32 (little-endian float32, row-major), and OUT_PREFIX.json holds every output's shape
// and the runtime's versions.
'use strict';

const fs = require('fs');
const { loadGraph, tf } = require('./graph_model');

async function main() {
  const job = JSON.parse(fs.readFileSync(process.argv[2], 'utf8'));
  const model = await loadGraph(job.model_json, job.model_bin);
  const bytes = fs.readFileSync(job.input.path);
  const values = new Float32Array(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength));
  const input = tf.tensor(values, job.input.shape, 'float32');
  let outputs = await model.executeAsync(input, job.outputs);
  if (!Array.isArray(outputs)) outputs = [outputs];
  const shapes = {};
  for (let i = 0; i < job.outputs.length; i++) {
    const data = await outputs[i].data();
    fs.writeFileSync(`${job.out_prefix}.${job.outputs[i]}.f32`, Buffer.from(data.buffer, data.byteOffset, data.byteLength));
    shapes[job.outputs[i]] = outputs[i].shape;
  }
  const versions = { 'tfjs-core': tf.version_core, backend: tf.getBackend() };
  fs.writeFileSync(`${job.out_prefix}.json`, JSON.stringify({ shapes, versions }));
}

main().catch((error) => {
  console.error(error);
  process.exit(1);
});
