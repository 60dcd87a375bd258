#!/usr/bin/env node
// Validates a .glb or .gltf file with the Khronos glTF-Validator and prints its report as JSON
// (issues.numErrors, numWarnings, numInfos, numHints, and the messages). Exit status 0 when the
// report was made, whatever it says; 2 when the file could not be read or validated at all.
//
// usage: node tools/node/validate_gltf.js FILE.glb
"use strict";
const fs = require("fs");
const path = require("path");
const validator = require("gltf-validator");

const file = process.argv[2];
if (!file) {
  console.error("usage: node validate_gltf.js FILE.glb|FILE.gltf");
  process.exit(2);
}
let bytes;
try {
  bytes = new Uint8Array(fs.readFileSync(file));
} catch (e) {
  console.error(`${file}: ${e.message}`);
  process.exit(2);
}
validator
  .validateBytes(bytes, {
    uri: path.basename(file),
    maxIssues: 0, // report them all
    // everything vtts writes is embedded: an external uri is itself a fault
    externalResourceFunction: (uri) => Promise.reject(`external resource ${uri} refused`),
  })
  .then((report) => {
    process.stdout.write(JSON.stringify(report, null, 1) + "\n");
  })
  .catch((error) => {
    console.error(`${file}: the validator failed: ${error}`);
    process.exit(2);
  });
