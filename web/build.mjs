// Builds the editor page into web/dist: the page's own files from src/ and, from
// node_modules, the three.js module and the orbit controls it imports. No bundler:
// the page loads ES modules through an import map, all from the meshpde server.
import { cpSync, mkdirSync, rmSync, existsSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const dist = join(here, 'dist');
const three = join(here, 'node_modules', 'three');
if (!existsSync(three)) {
  console.error('three.js is missing: run `npm ci` in web/ first');
  process.exit(1);
}
rmSync(dist, { recursive: true, force: true });
mkdirSync(join(dist, 'vendor'), { recursive: true });
cpSync(join(here, 'src'), dist, { recursive: true });
cpSync(join(three, 'build', 'three.module.js'), join(dist, 'vendor', 'three.module.js'));
cpSync(join(three, 'examples', 'jsm', 'controls', 'OrbitControls.js'), join(dist, 'vendor', 'OrbitControls.js'));
console.log(`built ${dist}`);
