// Drawing a drag without a GPU. A correct drag moves one region of the surface and
// leaves the rest as it is drawn, but a software rasterizer (SwiftShader, llvmpipe)
// spends most of a frame on the triangles that did not change. So, while a drag is on,
// the page draws the still part of the surface once into an image with its depth, and
// each frame copies that image (colour and depth) and draws only the triangles whose
// corners or shading can change, then everything else in the scene as usual. The
// picture is the same as drawing the whole surface (web.editor compares the two).
import * as THREE from 'three';

// The copy: one triangle over the view, writing the kept colour and depth of its pixel.
const COPY_VERTEX = `void main() { gl_Position = vec4(position.xy, 0.0, 1.0); }`;
const COPY_FRAGMENT = `
uniform sampler2D colour;
uniform sampler2D depth;
void main() {
  ivec2 p = ivec2(gl_FragCoord.xy);
  gl_FragColor = texelFetch(colour, p, 0);
  gl_FragDepth = texelFetch(depth, p, 0).x;
  #include <colorspace_fragment>
}`;

export function createStillDraw({ renderer, scene, camera }) {
  const copyMaterial = new THREE.ShaderMaterial({
    uniforms: { colour: { value: null }, depth: { value: null } },
    vertexShader: COPY_VERTEX, fragmentShader: COPY_FRAGMENT,
    // The depth test must be on for the depth to be written; every pixel passes it.
    depthTest: true, depthWrite: true, depthFunc: THREE.AlwaysDepth,
  });
  const copyGeometry = new THREE.BufferGeometry();
  copyGeometry.setAttribute('position', new THREE.BufferAttribute(new Float32Array([-1, -1, 0, 3, -1, 0, -1, 3, 0]), 3));
  const copy = new THREE.Mesh(copyGeometry, copyMaterial);
  copy.frustumCulled = false;
  const copyScene = new THREE.Scene();
  copyScene.add(copy);
  const copyCamera = new THREE.OrthographicCamera();

  let frozen = null;  // { target, moving, still, surfaces, covered }

  // Splits the surface for a drag that moves the vertices `ids`: a moved vertex changes
  // its position and the normals of its one ring, so the triangles drawn each frame
  // are those with a corner in the moved vertices' one ring (vertexFaces: the triangles
  // around each vertex, compressed rows). The rest is drawn now, once.
  // The vertices of an earlier split of the same drag stay in (they may not be back at rest).
  function freeze({ geometry, surfaces, triangles, vertexFaces, ids }) {
    const covered = frozen && frozen.geometry === geometry ? frozen.covered
      : new Uint8Array(vertexFaces.offsets.length - 1);
    thaw();
    const { offsets, faces } = vertexFaces;
    const nv = offsets.length - 1, nf = triangles.length / 3;
    const shaded = new Uint8Array(nv), moving = new Uint8Array(nf);
    for (const v of ids) covered[v] = 1;
    for (let v = 0; v < nv; ++v) {
      if (!covered[v]) continue;
      for (let k = offsets[v]; k < offsets[v + 1]; ++k)
        for (let c = 0; c < 3; ++c) shaded[triangles[3 * faces[k] + c]] = 1;
    }
    let count = 0;
    for (let v = 0; v < nv; ++v) {
      if (!shaded[v]) continue;
      for (let k = offsets[v]; k < offsets[v + 1]; ++k)
        if (!moving[faces[k]]) { moving[faces[k]] = 1; count += 1; }
    }
    // The moving triangles get their own small vertex arrays (the corners they use), so
    // that a frame sends the graphics driver those rather than the whole mesh's.
    const local = new Int32Array(nv).fill(-1), used = [];
    const movingIndex = new Uint32Array(3 * count), stillIndex = new Uint32Array(3 * (nf - count));
    for (let f = 0, a = 0, b = 0; f < nf; ++f)
      for (let c = 0; c < 3; ++c) {
        const v = triangles[3 * f + c];
        if (!moving[f]) { stillIndex[b++] = v; continue; }
        if (local[v] < 0) { local[v] = used.length; used.push(v); }
        movingIndex[a++] = local[v];
      }
    const part = (index, attributes) => {
      const g = new THREE.BufferGeometry();
      for (const [name, attribute] of Object.entries(attributes)) g.setAttribute(name, attribute);
      g.setIndex(new THREE.BufferAttribute(index, 1));
      g.boundingSphere = geometry.boundingSphere;
      return g;
    };
    const own = {};
    for (const name of Object.keys(geometry.attributes))
      own[name] = new THREE.BufferAttribute(new Float32Array(3 * used.length), 3).setUsage(THREE.DynamicDrawUsage);
    const size = renderer.getDrawingBufferSize(new THREE.Vector2());
    const target = new THREE.WebGLRenderTarget(size.x, size.y, { depthBuffer: true });
    target.texture.colorSpace = THREE.SRGBColorSpace;
    target.depthTexture = new THREE.DepthTexture(size.x, size.y);
    frozen = { target, moving: part(movingIndex, own), still: part(stillIndex, geometry.attributes), surfaces,
      geometry, covered, used: Uint32Array.from(used), movingTriangles: count, size };
    copyAttributes(Object.keys(own));

    // The still part alone (the background included), as the whole scene would draw it.
    const hidden = [];
    for (const o of scene.children)
      if (!surfaces.includes(o) && !o.isLight && !o.isCamera && o.visible) { hidden.push(o); o.visible = false; }
    for (const s of surfaces) s.geometry = frozen.still;
    renderer.setRenderTarget(target);
    renderer.render(scene, camera);
    renderer.setRenderTarget(null);
    for (const o of hidden) o.visible = true;
    for (const s of surfaces) s.geometry = frozen.moving;
    copyMaterial.uniforms.colour.value = target.texture;
    copyMaterial.uniforms.depth.value = target.depthTexture;
  }

  // Copies the moving corners' attributes `names` from the whole mesh's.
  function copyAttributes(names) {
    const { used, moving, geometry } = frozen;
    for (const name of names) {
      const from = geometry.getAttribute(name).array, to = moving.getAttribute(name);
      for (let k = 0; k < used.length; ++k) {
        const v = 3 * used[k];
        to.array[3 * k] = from[v]; to.array[3 * k + 1] = from[v + 1]; to.array[3 * k + 2] = from[v + 2];
      }
      to.needsUpdate = true;
    }
  }
  // After each update: the moved positions and their normals (the colours stay: new
  // ones end the split).
  function update() {
    if (frozen) copyAttributes(['position', 'normal']);
  }

  // Whether the kept image still holds: the same view size and no vertex moved outside
  // the split.
  function holds(ids) {
    if (!frozen) return false;
    const size = renderer.getDrawingBufferSize(new THREE.Vector2());
    if (size.x !== frozen.size.x || size.y !== frozen.size.y) return false;
    for (const v of ids) if (!frozen.covered[v]) return false;
    return true;
  }

  function thaw() {
    if (!frozen) return;
    for (const s of frozen.surfaces) s.geometry = frozen.geometry;
    frozen.target.depthTexture.dispose();
    frozen.target.dispose();
    frozen.moving.dispose();
    // The still part shares the mesh's vertex arrays: disposing of them would free the
    // mesh's own buffers, so only its triangle list goes.
    for (const name of Object.keys(frozen.still.attributes)) frozen.still.deleteAttribute(name);
    frozen.still.dispose();
    frozen = null;
  }

  // A frame: the kept image, then the scene with only the moving triangles of the surface.
  function draw() {
    renderer.render(copyScene, copyCamera);
    const autoClear = renderer.autoClear, background = scene.background;
    renderer.autoClear = false;
    scene.background = null;
    renderer.render(scene, camera);
    renderer.autoClear = autoClear;
    scene.background = background;
  }

  return {
    freeze, holds, update, thaw, draw,
    get active() { return frozen !== null; },
    get movingTriangles() { return frozen ? frozen.movingTriangles : 0; },
    get movingVertices() { return frozen ? frozen.used.length : 0; },
  };
}
