#!/usr/bin/env node
// Runs the Khronos glTF validator (npm package gltf-validator) on one .gltf/.glb file and exits
// non-zero when it reports errors, so tests and CI can check what penumbra writes.
//
//   node tools/validate-gltf.mjs FILE [VALIDATOR_DIR]
//
// VALIDATOR_DIR is the npm --prefix the package was installed under (setup.sh uses
// build/npm); the environment variable PENUMBRA_GLTF_VALIDATOR_DIR works too.
// Exit codes: 0 valid (warnings and hints are printed but allowed), 1 errors, 2 usage or
// validator not installed.
import { readFile } from 'node:fs/promises';
import { createRequire } from 'node:module';
import path from 'node:path';

const [file, dirArg] = process.argv.slice(2);
if (!file) {
  console.error('usage: node tools/validate-gltf.mjs FILE [VALIDATOR_DIR]');
  process.exit(2);
}
const dir = path.resolve(dirArg || process.env.PENUMBRA_GLTF_VALIDATOR_DIR || 'build/npm');

let validator;
try {
  validator = createRequire(path.join(dir, 'package.json'))('gltf-validator');
} catch (e) {
  console.error(`validate-gltf: gltf-validator is not installed under ${dir} (npm install --prefix ${dir} gltf-validator)`);
  process.exit(2);
}

const bytes = new Uint8Array(await readFile(file));
const base = path.dirname(path.resolve(file));
const report = await validator.validateBytes(bytes, {
  uri: path.basename(file),
  maxIssues: 100,
  // External buffers and images are resolved next to the file.
  externalResourceFunction: (uri) => readFile(path.join(base, decodeURIComponent(uri))).then((b) => new Uint8Array(b)),
});
const { numErrors, numWarnings, numInfos, numHints, messages } = report.issues;
for (const m of messages) {
  const severity = ['error', 'warning', 'info', 'hint'][m.severity] ?? m.severity;
  console.log(`${file}: ${severity}: ${m.code} ${m.pointer ?? ''} ${m.message}`);
}
console.log(`${file}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos, ${numHints} hints`);
process.exit(numErrors > 0 ? 1 : 0);
