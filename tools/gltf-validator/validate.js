// Validates glTF 2.0 files (.gltf or .glb) with the Khronos validator and prints one line per
// file: its errors and warnings and their codes. Exit status 0 when every file has neither,
// 1 when one has, 2 when a file cannot be read or the validator fails.
//
// Usage: node tools/gltf-validator/validate.js FILE...
'use strict';
const fs = require('fs');
const path = require('path');
const validator = require('gltf-validator');

async function validate(file) {
  const dir = path.dirname(file);
  const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
    uri: path.basename(file),
    maxIssues: 0,
    externalResourceFunction: (uri) =>
      new Promise((resolve, reject) => {
        fs.readFile(path.join(dir, decodeURIComponent(uri)), (error, data) =>
          error ? reject(error.toString()) : resolve(new Uint8Array(data)));
      }),
  });
  const issues = report.issues;
  const codes = [...new Set(issues.messages.filter((m) => m.severity <= 1).map((m) => m.code))];
  console.log(`${file}: ${issues.numErrors} errors, ${issues.numWarnings} warnings` +
              (codes.length ? ` (${codes.join(', ')})` : ''));
  return issues.numErrors + issues.numWarnings === 0;
}

(async () => {
  const files = process.argv.slice(2);
  if (files.length === 0) {
    console.error('usage: node validate.js FILE...');
    process.exit(2);
  }
  let clean = true;
  for (const file of files) {
    try {
      clean = (await validate(file)) && clean;
    } catch (error) {
      console.error(`${file}: ${error}`);
      process.exit(2);
    }
  }
  process.exit(clean ? 0 : 1);
})();
