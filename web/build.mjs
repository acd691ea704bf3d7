// Bundles the web front end of `occmap serve` into one flat folder: index.html, app.js,
// app.css and manifest.txt (one file name per line, read by the back end's embedding rule).
// Usage: node build.mjs --out DIR [--node-modules DIR]
// --node-modules: where `npm ci` put the packages (the build tree keeps its own copy so the
// source tree stays clean); default ./node_modules beside this file.
import { createRequire } from 'node:module';
import fs from 'node:fs';
import path from 'node:path';
import { fileURLToPath } from 'node:url';

const here = path.dirname(fileURLToPath(import.meta.url));
const args = process.argv.slice(2);
function arg(name, fallback) {
  const i = args.indexOf(name);
  if (i < 0) return fallback;
  if (i + 1 >= args.length) throw new Error(`build.mjs: ${name} needs a value`);
  return args[i + 1];
}
const outDir = path.resolve(arg('--out', path.join(here, 'dist')));
const nodeModules = path.resolve(arg('--node-modules', path.join(here, 'node_modules')));
const require = createRequire(path.join(nodeModules, 'noop.js'));
const esbuild = require('esbuild');

fs.mkdirSync(outDir, { recursive: true });
// Images referenced by Leaflet's and Geoman's CSS go inline so the folder stays three files.
const result = await esbuild.build({
  entryPoints: { app: path.join(here, 'src/main.js') },
  bundle: true,
  minify: true,
  sourcemap: false,
  format: 'iife',
  target: ['chrome100', 'firefox100', 'safari15'],
  outdir: outDir,
  nodePaths: [nodeModules],
  loader: { '.png': 'dataurl', '.svg': 'dataurl' },
  legalComments: 'none',
  logLevel: 'warning',
  metafile: true,
});
fs.copyFileSync(path.join(here, 'src/index.html'), path.join(outDir, 'index.html'));
const files = ['index.html', ...Object.keys(result.metafile.outputs).map((f) => path.basename(f))];
for (const f of fs.readdirSync(outDir)) {
  if (f !== 'manifest.txt' && !files.includes(f)) fs.rmSync(path.join(outDir, f), { recursive: true });
}
fs.writeFileSync(path.join(outDir, 'manifest.txt'), [...new Set(files)].sort().join('\n') + '\n');
