// Validates GLB files with the Khronos glTF validator; prints the report's issue summary
// and exits 1 when the file has errors.
const fs = require('fs');
const validator = require('gltf-validator');
(async () => {
  let failed = false;
  for (const path of process.argv.slice(2)) {
    const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(path)));
    const i = report.issues;
    console.log(JSON.stringify({path, errors: i.numErrors, warnings: i.numWarnings, infos: i.numInfos,
      messages: i.messages.filter(m => m.severity <= 1).map(m => `${m.code} ${m.pointer || ''} ${m.message}`)}));
    if (i.numErrors > 0) failed = true;
  }
  process.exit(failed ? 1 : 0);
})();
