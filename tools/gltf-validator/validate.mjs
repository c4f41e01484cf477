// Validate one glTF/GLB file with the Khronos glTF validator and print its JSON report.
// Usage: node validate.mjs path/to/model.glb
// Exit status: 0 when the report has no errors, 1 when it has errors, 2 on bad usage or unreadable input.
import { readFile } from "node:fs/promises";
import { createRequire } from "node:module";

const require = createRequire(import.meta.url);
const validator = require("gltf-validator");

const file = process.argv[2];
if (!file) {
  console.error("usage: node validate.mjs <model.glb|model.gltf>");
  process.exit(2);
}

try {
  const bytes = new Uint8Array(await readFile(file));
  const report = await validator.validateBytes(bytes, { uri: file, maxIssues: 100 });
  console.log(JSON.stringify(report, null, 2));
  process.exit(report.issues.numErrors > 0 ? 1 : 0);
} catch (error) {
  console.error(`cannot validate ${file}: ${error}`);
  process.exit(2);
}
