// The vtts serve page: a head that speaks what is typed (or what a script sends), live. It opens a
// session (client.js), loads the session's head as glTF (the web player's scene, head.js) and,
// every animation frame, poses the head with the face frame of the audio's current time: the
// streamed parameter values (FAPs, visemes, expressions) go through the model's tables as the
// glTF's morph targets and Transform nodes encode them.
//
// Query parameters: model=NAME (default: the server's first), background=transparent|RRGGBB,
// bar=0 (no text box), seed=N.
//
// For scripts: document.title becomes "ready" once the head is drawn and the session open, and
// window.vtts has say(text), append(text), flush(), stop(), on(name, fn) (and off) for 'audiostart',
// 'end', 'error' (and client.js's other events), hold(values) (show a parameter vector,
// N_PARAMS long, instead of the stream; null to follow it again), level(), sync(), session.

import * as THREE from 'three';
import { addLights, applyMorph, cpuMorphs, findCamera, fitCamera, wantsAntialias } from '/player/head.js';
import { N_PARAMS, Session } from '/vtts/client.js';

const config = JSON.parse(document.getElementById('vtts-config').textContent);
const query = new URLSearchParams(location.search);
const $ = (id) => document.getElementById(id);

function fail(error) {
  const text = (error && (error.message || error.type)) || String(error);
  console.error(error);
  $('message').textContent = `vtts serve: ${text}`;
  document.title = `error: ${text}`;
}
window.addEventListener('unhandledrejection', (e) => fail(e.reason));

// ---- the rig: parameter values → morph weights and Transform fields ----

// Each morph target "LABEL#k" of a mesh is interval k of a MIAP's table on it
// (docs/web.md, "ADTs as morph targets"): its weight is how far the MIAP's value has moved
// through [from, to], the first interval open towards -∞ and the last towards +∞.
function meshRig(mesh, miaps) {
  const names = mesh.userData.targetNames || [];
  const intervals = (mesh.userData.vtts && mesh.userData.vtts.intervals) || [];
  const last = new Map();
  const parsed = names.map((name) => {
    const [label, k] = name.split('#');
    last.set(label, Math.max(last.get(label) || 0, Number(k)));
    return [label, Number(k)];
  });
  const rig = { mesh, param: [], lo: [], hi: [], from: [], span: [] };
  parsed.forEach(([label, k], i) => {
    const [from, to] = intervals[i] || [0, 1];
    rig.param.push(label in miaps ? miaps[label] : -1);
    rig.lo.push(k === 0 ? -Infinity : Math.min(from, to));
    rig.hi.push(k === last.get(label) ? Infinity : Math.max(from, to));
    rig.from.push(from);
    rig.span.push(to - from || 1);
  });
  return rig;
}

function axisAngle(axis, angle) {
  const v = new THREE.Vector3(axis[0], axis[1], axis[2]);
  if (v.lengthSq() === 0) return new THREE.Quaternion();
  return new THREE.Quaternion().setFromAxisAngle(v.normalize(), angle);
}

function transformRig(root, table) {
  const nodes = new Map();
  root.traverse((o) => { if (o.userData && o.userData.name) nodes.set(o.userData.name, o); });
  return table.map((t) => {
    const node = nodes.get(t.node) || null;
    return { ...t, node, rest: node ? node.position.clone() : null };
  }).filter((t) => t.node !== null);
}

function pose(rig, p) {
  for (const m of rig.meshes) {
    const w = m.mesh.morphTargetInfluences;
    for (let i = 0; i < m.param.length; i++) {
      const f = m.param[i] >= 0 ? p[m.param[i]] : 0;
      w[i] = (Math.min(Math.max(f, m.lo[i]), m.hi[i]) - m.from[i]) / m.span[i];
    }
  }
  for (const entry of rig.morphs) applyMorph(entry);
  for (const t of rig.transforms) {
    const f = t.param.map((i) => p[i]);
    if (t.field === 'rotation') {
      const q = axisAngle(t.neutral, t.neutral[3]);
      f.forEach((v, i) => { if (v) q.multiply(axisAngle(t.axes[i], v * t.unit[i])); });
      t.node.quaternion.copy(q);
    } else {
      const d = [0, 0, 0];
      f.forEach((v, i) => { for (let a = 0; a < 3; a++) d[a] += v * t.unit[i][a]; });
      if (t.field === 'translation') {
        t.node.position.set(t.rest.x + d[0], t.rest.y + d[1], t.rest.z + d[2]);
      } else {
        t.node.scale.set(t.neutral[0] + d[0], t.neutral[1] + d[1], t.neutral[2] + d[2]);
      }
    }
  }
}

// ---- the page ----

async function main() {
  const background = query.get('background') || '';
  if (background === 'transparent') {
    document.documentElement.style.background = 'transparent';
    document.body.style.background = 'transparent';
  } else if (/^[0-9a-f]{6}$/i.test(background)) {
    document.body.style.background = `#${background}`;
  }
  if (query.get('bar') === '0') $('bar').classList.add('hidden');

  const options = {};
  if (query.get('model')) options.model = query.get('model');
  if (query.get('seed')) options.seed = Number(query.get('seed'));
  const session = await Session.connect(location.origin, options);

  const renderer = new THREE.WebGLRenderer({ antialias: wantsAntialias(query.get('antialias')), alpha: true });
  renderer.setClearColor(0x000000, 0);
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  document.body.prepend(renderer.domElement);

  const { GLTFLoader } = await import('three/addons/loaders/GLTFLoader.js');
  const gltf = await new GLTFLoader().loadAsync(session.opened.glb);
  const scene = gltf.scene;
  const camera = findCamera(gltf);
  if (camera === null || !camera.isPerspectiveCamera) throw new Error('the head has no camera vtts');
  const design = { aspect: camera.aspect, fov: camera.fov };
  addLights(scene, camera);
  const rig = { meshes: [], morphs: cpuMorphs(scene), transforms: transformRig(scene, session.opened.rig.transforms) };
  for (const entry of rig.morphs) rig.meshes.push(meshRig(entry.mesh, session.opened.rig.miaps));

  function resize() {
    renderer.setSize(window.innerWidth, window.innerHeight, false);
    fitCamera(camera, design.aspect, design.fov, window.innerWidth, window.innerHeight);
    dirty = true;
  }
  let dirty = true;
  window.addEventListener('resize', resize);
  resize();

  // ---- drawing on the audio clock ----
  const rest = new Float32Array(N_PARAMS);
  let held = null;
  let shown = null;
  let framesDrawn = 0;
  const sync = { frames: 0, maxAhead: -Infinity, maxBehind: 0 };
  function frame() {
    let p = rest;
    if (held !== null) {
      p = held;
    } else {
      const now = session.frameAt();
      if (now !== null) {
        p = now.values;
        const ahead = now.frameTime - now.audioTime; // ≤ 0: the face is never ahead of its sound
        sync.frames += 1;
        sync.maxAhead = Math.max(sync.maxAhead, ahead);
        sync.maxBehind = Math.max(sync.maxBehind, -ahead);
      }
    }
    if (p !== shown || dirty) {
      pose(rig, p);
      renderer.render(scene, camera);
      framesDrawn += 1;
      shown = p;
      dirty = false;
    }
    requestAnimationFrame(frame);
  }

  $('bar').addEventListener('submit', (e) => {
    e.preventDefault();
    const text = $('text').value;
    if (text.trim()) session.say(text);
  });
  $('stop').addEventListener('click', () => { session.stopMicrophone(); session.stop(); });
  $('mic').addEventListener('click', async () => {
    const button = $('mic');
    if (session.mic) { session.stopMicrophone(); button.setAttribute('aria-pressed', 'false'); return; }
    try {
      await session.microphone();
      button.setAttribute('aria-pressed', 'true');
    } catch (e) {
      $('message').textContent = `no microphone: ${e.message}`;
    }
  });
  session.on('error', (e) => { $('message').textContent = e.message; });
  session.on('clause', () => { $('message').textContent = ''; });

  window.vtts = {
    session,
    say: (text) => session.say(text),
    append: (text) => session.append(text),
    flush: () => session.flush(),
    stop: () => session.stop(),
    listen: (rate, options) => session.listen(rate, options),
    sendAudio: (pcm) => session.sendAudio(pcm),
    microphone: () => session.microphone(),
    stopMicrophone: () => session.stopMicrophone(),
    on: (name, fn) => session.on(name, fn),
    off: (name, fn) => session.off(name, fn),
    hold: (values) => { held = values === null ? null : Float32Array.from(values); dirty = true; },
    level: () => session.level(),
    sync: () => ({ ...sync }),
    get framesDrawn() { return framesDrawn; },
    get underruns() { return session.stats.underruns; },
  };
  $('message').textContent = '';
  frame();
  requestAnimationFrame(() => requestAnimationFrame(() => { document.title = 'ready'; }));
}

main().catch(fail);
