// A TF.js graph model read from its model.json and one weights file, on the pure-JS CPU backend: shared by
// reference.js (the COCO CenterNet) and graph_outputs.js (any graph, e.g. NanoDet).
'use strict';

const fs = require('fs');
const tf = require('@tensorflow/tfjs-core');
require('@tensorflow/tfjs-backend-cpu');
const tfconv = require('@tensorflow/tfjs-converter');

function fileHandler(jsonPath, binPath) {
  return {
    load: async () => {
      const graph = JSON.parse(fs.readFileSync(jsonPath, 'utf8'));
      const bin = fs.readFileSync(binPath);
      return {
        modelTopology: graph.modelTopology,
        format: graph.format,
        generatedBy: graph.generatedBy,
        convertedBy: graph.convertedBy,
        signature: graph.signature,
        weightSpecs: graph.weightsManifest.flatMap((group) => group.weights),
        weightData: bin.buffer.slice(bin.byteOffset, bin.byteOffset + bin.byteLength),
      };
    },
  };
}

// The graph model at jsonPath with its weights at binPath, once the CPU backend is ready.
async function loadGraph(jsonPath, binPath) {
  await tf.setBackend('cpu');
  await tf.ready();
  return tfconv.loadGraphModel(fileHandler(jsonPath, binPath));
}

module.exports = { loadGraph, tf };
