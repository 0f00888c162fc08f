// GLB files written by `progiso extract -o x.glb`, checked by the Khronos glTF validator (the
// npm package gltf-validator): no error, and the counts the command reports. Run by ctest
// (exporters.glb_validator): node web/tests/validate_glb.mjs PROGISO_EXE VOLUME DIMS TYPE ISO DIR
// Exit 77 (skipped) without the validator or the volume.
import { execFileSync } from 'node:child_process';
import { existsSync, readFileSync } from 'node:fs';

const [exe, volume, dims, type, iso, dir] = process.argv.slice(2);
if (!existsSync(volume)) { console.log(`skipped: no ${volume}`); process.exit(77); }
let validator;
try { validator = (await import('gltf-validator')).default; } catch { console.log('skipped: no gltf-validator (npm ci in web/)'); process.exit(77); }

let failed = false;
const cases = [
  ['with normals', ['--normals'], Number(iso)],
  ['positions only', [], Number(iso)],
  ['by error', ['--error', '1'], Number(iso)],
  ['empty (isovalue above the data)', [], 1e9],
];
for (const [name, extra, w] of cases) {
  const out = `${dir}/validate-${cases.findIndex((c) => c[0] === name)}.glb`;
  execFileSync(exe, ['extract', volume, '--dims', dims, '--type', type, '--iso', String(w), '-o', out, ...extra],
               { stdio: ['ignore', 'ignore', 'inherit'] });
  const bytes = new Uint8Array(readFileSync(out));
  const report = await validator.validateBytes(bytes);
  const { numErrors, numWarnings } = report.issues;
  const info = report.info ?? {};
  console.log(`${name}: ${bytes.length} bytes, ${numErrors} errors, ${numWarnings} warnings, ` +
              `${info.totalTriangleCount ?? 0} triangles, ${info.totalVertexCount ?? 0} vertices`);
  if (numErrors !== 0) {
    failed = true;
    for (const m of report.issues.messages.slice(0, 10)) console.error(`  ${m.code}: ${m.message} (${m.pointer ?? ''})`);
  }
  if (w < 1e9 && !(info.totalTriangleCount > 0)) { failed = true; console.error('  no triangles'); }
}
if (failed) { console.error('FAIL'); process.exit(1); }
console.log('ok');
