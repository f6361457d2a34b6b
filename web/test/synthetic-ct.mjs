// A generated CT for timing the editor's slices: 512 x 512 x 300 int16 voxels of
// 0.7 x 0.7 x 1 mm (a typical abdominal CT's size), a body, a spine and a winding
// aorta in air, written as one MetaImage file.
import { writeFileSync } from 'node:fs';

export function writeSyntheticCT(file, [nx, ny, nz] = [512, 512, 300]) {
  const values = new Int16Array(nx * ny * nz);
  for (let k = 0; k < nz; ++k)
    for (let j = 0; j < ny; ++j)
      for (let i = 0; i < nx; ++i) {
        const x = (i - nx / 2) * 0.7, y = (j - ny / 2) * 0.7;
        let v = -1000;
        if ((x / 160) ** 2 + (y / 110) ** 2 < 1) v = 40;
        if (x ** 2 + (y - 60) ** 2 < 15 ** 2) v = 700;
        if ((x + 10) ** 2 + (y + 20) ** 2 < (12 + 2 * Math.sin(k / 20)) ** 2) v = 300;
        values[i + nx * (j + ny * k)] = v;
      }
  const header = ['ObjectType = Image', 'NDims = 3', `DimSize = ${nx} ${ny} ${nz}`, 'ElementSpacing = 0.7 0.7 1',
    `Offset = ${-0.35 * nx} ${-0.35 * ny} ${-0.5 * nz}`, 'TransformMatrix = 1 0 0 0 1 0 0 0 1', 'ElementType = MET_SHORT',
    'ElementByteOrderMSB = False', 'ElementDataFile = LOCAL', ''].join('\n');
  writeFileSync(file, Buffer.concat([Buffer.from(header), Buffer.from(values.buffer)]));
}
