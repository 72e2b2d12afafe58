// Validate a glTF/GLB file with the Khronos glTF validator; print its report as JSON.
// Usage: node tests/gltf_validate.js FILE
const fs = require('fs');
const validator = require('gltf-validator');

const path = process.argv[2];
const data = new Uint8Array(fs.readFileSync(path));
validator.validateBytes(data, { maxIssues: 200 })
  .then((report) => { process.stdout.write(JSON.stringify(report)); })
  .catch((error) => { process.stderr.write(String(error)); process.exit(1); });
