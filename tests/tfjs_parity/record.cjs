// Runs TF.js graph models with @tensorflow/tfjs on its pure-JavaScript CPU backend and writes
// their outputs, for hkpd's parity fixtures. Driven by tests/record_tfjs_parity.py:
//   node record.cjs job.json
// job.json: {"models": [{"json": ".../model.json", "inputs": {"name": {"file", "dtype",
// "shape"}}, "outputs": ["name", ...], "out_dir": "..."}]}. Each output is written as raw
// little-endian values to out_dir/<index>.bin with out_dir/outputs.json listing name, dtype and
// shape. Weights are read from the shards beside model.json (nothing is fetched).
'use strict';
const fs = require('fs');
const path = require('path');
const tf = require('@tensorflow/tfjs');

function artifacts(jsonPath) {
  const model = JSON.parse(fs.readFileSync(jsonPath, 'utf8'));
  const specs = [];
  const buffers = [];
  for (const group of model.weightsManifest) {
    for (const spec of group.weights) specs.push(spec);
    for (const shard of group.paths) buffers.push(fs.readFileSync(path.join(path.dirname(jsonPath), shard)));
  }
  const joined = Buffer.concat(buffers);
  return {
    modelTopology: model.modelTopology,
    format: model.format,
    generatedBy: model.generatedBy,
    convertedBy: model.convertedBy,
    signature: model.signature,
    userDefinedMetadata: model.userDefinedMetadata,
    weightSpecs: specs,
    weightData: joined.buffer.slice(joined.byteOffset, joined.byteOffset + joined.byteLength),
  };
}

function inputTensor(spec) {
  const bytes = fs.readFileSync(spec.file);
  const buffer = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
  const values = spec.dtype === 'int32' ? new Int32Array(buffer) : new Float32Array(buffer);
  return tf.tensor(values, spec.shape, spec.dtype);
}

async function runModel(job) {
  const handler = { load: async () => artifacts(job.json) };
  const model = await tf.loadGraphModel(handler);
  const feeds = {};
  for (const [name, spec] of Object.entries(job.inputs)) feeds[name] = inputTensor(spec);
  let results = model.execute(feeds, job.outputs);
  if (!Array.isArray(results)) results = [results];
  fs.mkdirSync(job.out_dir, { recursive: true });
  const listing = [];
  for (let index = 0; index < results.length; index++) {
    const values = results[index].dataSync();
    fs.writeFileSync(path.join(job.out_dir, `${index}.bin`), Buffer.from(values.buffer, values.byteOffset, values.byteLength));
    listing.push({ name: job.outputs[index], dtype: results[index].dtype, shape: results[index].shape });
  }
  fs.writeFileSync(path.join(job.out_dir, 'outputs.json'), JSON.stringify(listing));
}

async function main() {
  await tf.setBackend('cpu');
  await tf.ready();
  const job = JSON.parse(fs.readFileSync(process.argv[2], 'utf8'));
  for (const modelJob of job.models) await runModel(modelJob);
  console.log(JSON.stringify({ tfjs: tf.version.tfjs, backend: tf.getBackend() }));
}

main().catch((error) => { console.error(error); process.exit(1); });
