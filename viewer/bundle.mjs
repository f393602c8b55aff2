// Bundles the page's code with three.js (pinned by package-lock.json) into
// crates/view/page/viewer.js, which `crowd view` compiles in: the page then works offline.
// `node bundle.mjs --check` fails if the committed bundle is not what the sources give.
import * as esbuild from 'esbuild';
import { readFileSync, writeFileSync } from 'node:fs';
import { fileURLToPath } from 'node:url';

const here = fileURLToPath(new URL('.', import.meta.url));
const out = `${here}../crates/view/page/viewer.js`;
const result = await esbuild.build({
  entryPoints: [`${here}src/main.js`],
  bundle: true,
  format: 'esm',
  minify: true,
  target: 'es2022',
  legalComments: 'eof',
  write: false,
  logLevel: 'warning',
});
const code = result.outputFiles[0].contents;
if (process.argv.includes('--check')) {
  const committed = readFileSync(out);
  if (Buffer.compare(Buffer.from(code), committed) !== 0) {
    console.error(`${out} is not the bundle of viewer/src: run \`node viewer/bundle.mjs\``);
    process.exit(1);
  }
  console.log(`${out} is up to date`);
} else {
  writeFileSync(out, code);
  console.log(`wrote ${out} (${code.length} bytes)`);
}
