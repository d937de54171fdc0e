// Validates glTF/GLB files with the Khronos glTF Validator (npm gltf-validator) and prints one
// JSON line per file: {"file", "errors", "warnings", "infos", "messages": [first errors]}.
// Exit code 0 even when a file has errors: cli/tests/gltf.rs reads the counts.
//
//   node validate.mjs FILE.glb [FILE.gltf ...]
import { readFileSync } from 'node:fs';
import validator from 'gltf-validator';

for (const file of process.argv.slice(2)) {
  const report = await validator.validateBytes(new Uint8Array(readFileSync(file)), {
    uri: file,
    maxIssues: 50,
    externalResourceFunction: () => Promise.reject(new Error('external resources are not used')),
  });
  const issues = report.issues;
  const messages = issues.messages
    .filter((m) => m.severity === 0)
    .slice(0, 10)
    .map((m) => `${m.code} ${m.pointer ?? ''}: ${m.message}`);
  console.log(JSON.stringify({
    file, errors: issues.numErrors, warnings: issues.numWarnings, infos: issues.numInfos, messages,
    warningMessages: issues.messages.filter((m) => m.severity === 1).slice(0, 10).map((m) => `${m.code} ${m.pointer ?? ''}: ${m.message}`),
  }));
}
