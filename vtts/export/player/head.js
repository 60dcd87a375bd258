// What the vtts web player and the vtts serve page share: the scene of a .glb that vtts wrote (its
// camera "vtts", vtts render's lights, the heads) and its morph targets applied on the CPU.

import * as THREE from 'three';

// ---- the scene -----------------------------------------------------------------------------------

export function findCamera(gltf) {
  for (const c of gltf.cameras) {
    if (c.name === 'vtts' || (c.parent && c.parent.name === 'vtts')) return c;
  }
  return gltf.cameras[0] || null;
}

// vtts render's lights: ambient 0.35, a key light (2.2) from above left of the camera and a fill
// light (0.8) from the right, both directional. three.js divides ambient light by π as pyrender
// does not, hence the factor. The lights ride with the camera, so orbiting keeps the face lit.
export function addLights(scene, camera) {
  scene.add(new THREE.AmbientLight(0xffffff, 0.35 * Math.PI));
  for (const [intensity, ax, ay] of [[2.2, -0.35, -0.3], [0.8, -0.1, 0.5]]) {
    const light = new THREE.DirectionalLight(0xffffff, intensity);
    // pyrender's light shines along its -z; rotated about x by ax, then about y by ay
    const along = new THREE.Vector3(0, 0, -1).applyEuler(new THREE.Euler(ax, ay, 0, 'YXZ'));
    light.position.copy(along).multiplyScalar(-1);
    camera.add(light);
    camera.add(light.target); // at the camera's origin: the light shines along `along`
  }
  if (camera.parent === null) scene.add(camera);
}

// The heads: the scene's top-level nodes with meshes, in the order vtts wrote them.
export function findHeads(root) {
  const heads = [];
  for (const child of root.children) {
    let meshes = false;
    child.traverse((o) => { meshes = meshes || o.isMesh; });
    if (meshes) heads.push(child);
  }
  return heads;
}

// Fit the vertical field of view so that a window narrower than the exported image still shows
// all that the vtts camera shows (the export's width), and a wider one shows more at the sides.
export function fitCamera(camera, designAspect, designFov, width, height) {
  camera.aspect = width / height;
  const tanHalf = Math.tan(THREE.MathUtils.degToRad(designFov) / 2);
  const scale = Math.max(1, designAspect / camera.aspect);
  camera.fov = THREE.MathUtils.radToDeg(2 * Math.atan(tanHalf * scale));
  camera.updateProjectionMatrix();
}

// ---- morph targets on the CPU ----------------------------------------------------------------------

// The heads' morph targets (the ADTs) are applied here, in JavaScript, instead of in three.js's
// vertex shader. The shader loops over every target of a mesh for every vertex, weighted or not;
// in software WebGL (SwiftShader, what a machine without a GPU has) a face of 5,000 vertices and
// 75 targets then takes 100 ms a frame. Here only the targets whose weight is not 0 cost
// anything (a few dozen at a time, 1 ms), and the mesh is drawn as a plain one: positions and
// normals are the base plus the weighted deltas, as the shader would have made them.

function floats(attribute) {
  // an attribute's values as a plain Float32Array (de-interleaved, de-normalized)
  if (!attribute.isInterleavedBufferAttribute && !attribute.normalized &&
      attribute.array instanceof Float32Array) {
    return attribute.array;
  }
  const out = new Float32Array(attribute.count * attribute.itemSize);
  for (let i = 0; i < attribute.count; i++) {
    for (let k = 0; k < attribute.itemSize; k++) {
      out[i * attribute.itemSize + k] = attribute.getComponent(i, k);
    }
  }
  return out;
}

export function cpuMorphs(scene) {
  const users = new Map();
  scene.traverse((o) => {
    if (o.isMesh && o.geometry.morphAttributes.position) {
      users.set(o.geometry, (users.get(o.geometry) || 0) + 1);
    }
  });
  const morphs = [];
  scene.traverse((mesh) => {
    if (!mesh.isMesh || !mesh.geometry.morphAttributes.position) return;
    // a geometry shown by several nodes (VRML USE) gets a copy per node: each has its weights
    if (users.get(mesh.geometry) > 1) mesh.geometry = mesh.geometry.clone();
    const g = mesh.geometry;
    const deltas = (name) => {
      const base = g.attributes[name];
      const targets = g.morphAttributes[name];
      if (!base || !targets || targets.length === 0) return null;
      const plain = new THREE.BufferAttribute(floats(base).slice(), base.itemSize);
      plain.setUsage(THREE.DynamicDrawUsage);
      g.setAttribute(name, plain);
      const rest = plain.array.slice();
      const moves = targets.map((t) => {
        const d = floats(t);
        if (g.morphTargetsRelative) return d;
        return d.map((v, i) => v - rest[i]); // absolute targets: their difference to the base
      });
      return { attribute: plain, rest, moves };
    };
    const entry = { mesh, position: deltas('position'), normal: deltas('normal'), last: null };
    g.morphAttributes = {}; // three.js draws the base attributes, which applyMorph fills
    mesh.frustumCulled = false; // the base's bounds do not hold the morphed face
    morphs.push(entry);
  });
  return morphs;
}

export function applyMorph(entry) {
  const w = entry.mesh.morphTargetInfluences;
  if (entry.last !== null && entry.last.every((v, i) => v === w[i])) return;
  entry.last = Array.from(w);
  for (const part of [entry.position, entry.normal]) {
    if (part === null) continue;
    const out = part.attribute.array;
    out.set(part.rest);
    for (let t = 0; t < part.moves.length; t++) {
      const weight = w[t];
      if (!weight) continue;
      const d = part.moves[t];
      for (let i = 0; i < out.length; i++) out[i] += weight * d[i];
    }
    part.attribute.needsUpdate = true;
  }
}

// Multisampling (antialias) costs a software rasterizer (Mesa's llvmpipe, SwiftShader: a machine
// without a GPU) half its frame rate, so it is left to real GPUs, as vtts leaves supersampling
// to stills. asked ('1' or '0', the page's ?antialias=) decides instead.
export function wantsAntialias(asked) {
  if (asked !== null && asked !== undefined) return asked === '1';
  const probe = document.createElement('canvas').getContext('webgl2');
  if (!probe) return true;
  const info = probe.getExtension('WEBGL_debug_renderer_info');
  const name = String(probe.getParameter(info ? info.UNMASKED_RENDERER_WEBGL : probe.RENDERER));
  const lose = probe.getExtension('WEBGL_lose_context');
  if (lose) lose.loseContext();
  return !/llvmpipe|softpipe|swiftshader|software/i.test(name);
}

