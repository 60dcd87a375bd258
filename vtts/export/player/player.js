// The vtts web player: plays the animated glTF that vtts wrote beside this file, in step with its
// audio. Nothing here is MPEG-4 specific: the .glb holds the heads, their ADTs as morph targets
// and Transform ADTs as rotation channels, one animation of the whole utterance, and a camera
// named "vtts" (the camera vtts render uses); three.js's GLTFLoader and AnimationMixer play it.
//
// Query parameters (index.html?t=1.5&paused=1):
//   t=SECONDS        start at that time
//   paused=1         do not play: show the frame at t (a still; the control bar appears when the
//                    pointer moves), and set document.title to "ready" once it is drawn
//   head=N|NAME      show only that head (1 = the first) when there are several
//   background=transparent | RRGGBB   the page's background (default: vtts render's)
//   antialias=1|0    multisampling (default: on, except on software renderers)
//
// The animation follows the audio clock: every frame poses the heads at the audio element's
// currentTime (extrapolated by at most 0.1 s between its updates, which some browsers make
// coarsely), so sound and mouth cannot drift apart however long the utterance is. Without audio
// (vtts play of a stream without --audio) a wall clock stands in for it.
//
// window.vttsPlayer gives scripts (tests, benchmarks) the player: play(), pause(), seek(t),
// time(), duration, framesDrawn, clockSource().

import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import {
  addLights, applyMorph, cpuMorphs, findCamera, findHeads, fitCamera, wantsAntialias,
} from './head.js';

const config = JSON.parse(document.getElementById('vtts-config').textContent);
const query = new URLSearchParams(location.search);
const $ = (id) => document.getElementById(id);

function fail(error) {
  const text = (error && (error.message || error.type)) || String(error);
  console.error(error);
  $('message').textContent = `The vtts player failed: ${text}`;
  document.title = `error: ${text}`;
}
window.addEventListener('error', (e) => fail(e.error || e.message));
window.addEventListener('unhandledrejection', (e) => fail(e.reason));

// ---- the clock -----------------------------------------------------------------------------------

// How far the clock runs ahead of the audio's currentTime between two of its updates (seconds).
const MAX_AHEAD = 0.1;

// Media time in seconds, driven by the audio element while there is audio to play, else by
// performance.now(). seek() and pause() hold it; play() runs it from where it is.
class Clock {
  constructor(audio, duration) {
    this.audio = audio;
    this.duration = duration;
    this.playing = false;
    this.held = 0; // the time while paused, or where the wall clock started
    this.wallStart = 0; // performance.now() when the wall clock started
    this.lastAudio = -1; // the audio's currentTime when it last changed, and when that was
    this.lastAudioAt = 0;
    this.running = false; // the audio's time has moved since play() or seek()
    this.last = 0;
  }

  audioCovers(t) {
    const a = this.audio;
    return a !== null && Number.isFinite(a.duration) && t < a.duration - 1e-3;
  }

  source() {
    return this.playing && this.audioCovers(this.last) && !this.audio.paused ? 'audio' : 'wall';
  }

  time() {
    if (!this.playing) return this.held;
    const now = performance.now();
    let t;
    if (this.audio !== null && !this.audio.paused && !this.audio.ended) {
      const a = this.audio.currentTime;
      if (a !== this.lastAudio) {
        // extrapolate only once the audio is seen running: it takes a moment to start
        this.running = this.lastAudio >= 0;
        this.lastAudio = a;
        this.lastAudioAt = now;
      }
      const since = this.running ? (now - this.lastAudioAt) / 1000 : 0;
      const ahead = Math.min(since * this.audio.playbackRate, MAX_AHEAD);
      // never backwards while playing, never more than MAX_AHEAD ahead of the audio
      t = Math.max(a + ahead, Math.min(this.last, a + MAX_AHEAD));
    } else {
      t = this.held + (now - this.wallStart) / 1000;
    }
    if (t >= this.duration) {
      t = this.duration;
      this.pause(t);
    }
    this.last = t;
    return t;
  }

  async play() {
    if (this.playing) return;
    if (this.held >= this.duration - 1e-6) this.seek(0);
    this.playing = true;
    this.last = this.held;
    this.wallStart = performance.now();
    this.lastAudio = -1;
    this.running = false;
    if (this.audioCovers(this.held)) {
      this.audio.currentTime = this.held;
      try {
        await this.audio.play();
      } catch (e) {
        // the browser wants a user gesture first: stay paused until the play button is pressed
        this.playing = false;
        throw e;
      }
    }
  }

  pause(at) {
    this.held = at === undefined ? this.time() : at;
    this.playing = false;
    if (this.audio !== null && !this.audio.paused) this.audio.pause();
  }

  seek(t) {
    t = Math.min(Math.max(Number(t) || 0, 0), this.duration);
    const wasPlaying = this.playing;
    this.held = t;
    this.last = t;
    this.wallStart = performance.now();
    this.lastAudio = -1;
    this.running = false;
    if (this.audio !== null && this.audioCovers(t)) {
      this.audio.currentTime = t;
      if (wasPlaying && this.audio.paused) this.audio.play().catch(() => {});
    } else if (this.audio !== null && !this.audio.paused) {
      this.audio.pause(); // past the audio's end the wall clock runs on alone
    }
  }

  // the audio ended before the animation did: the wall clock takes over from there
  audioEnded() {
    if (!this.playing) return;
    this.held = this.audio.duration;
    this.wallStart = performance.now();
  }
}

// ---- the player ----------------------------------------------------------------------------------

async function main() {
  const background = query.get('background') || '';
  if (background === 'transparent') {
    document.documentElement.style.background = 'transparent';
    document.body.style.background = 'transparent';
  } else if (/^[0-9a-f]{6}$/i.test(background)) {
    document.body.style.background = `#${background}`;
  }

  const renderer = new THREE.WebGLRenderer({ antialias: wantsAntialias(query.get('antialias')), alpha: true });
  renderer.setClearColor(0x000000, 0);
  renderer.setPixelRatio(window.devicePixelRatio || 1);
  renderer.setSize(window.innerWidth, window.innerHeight, false);
  document.body.prepend(renderer.domElement);

  const gltf = await new GLTFLoader().loadAsync(config.glb);
  const scene = gltf.scene;
  const camera = findCamera(gltf);
  if (camera === null || !camera.isPerspectiveCamera) {
    throw new Error(`${config.glb} has no perspective camera named vtts`);
  }
  const design = { aspect: camera.aspect, fov: camera.fov };
  camera.updateMatrixWorld(true);
  const home = { position: camera.getWorldPosition(new THREE.Vector3()),
    quaternion: camera.getWorldQuaternion(new THREE.Quaternion()) };
  // the camera leaves its node so that the orbit controls move it in world coordinates
  scene.attach(camera);
  addLights(scene, camera);

  const morphs = cpuMorphs(scene);
  const heads = findHeads(scene);
  const bounds = new THREE.Box3().setFromObject(scene);
  const homeTarget = new THREE.Vector3();
  {
    // orbit about the point of the heads' centre that lies on the camera's line of sight
    const forward = new THREE.Vector3(0, 0, -1).applyQuaternion(home.quaternion);
    const centre = bounds.getCenter(new THREE.Vector3());
    const distance = Math.max(centre.clone().sub(home.position).dot(forward), camera.near * 2);
    homeTarget.copy(home.position).addScaledVector(forward, distance);
  }

  const mixer = new THREE.AnimationMixer(scene);
  const actions = gltf.animations.map((clip) => {
    const action = mixer.clipAction(clip);
    action.setLoop(THREE.LoopOnce, 1);
    action.clampWhenFinished = true;
    action.play();
    return action;
  });
  const clipEnd = Math.max(0, ...gltf.animations.map((c) => c.duration));

  const audio = config.audio ? $('audio') : null;
  let duration = Math.max(config.duration || 0, clipEnd);
  if (audio !== null) {
    // the audio is played from memory: static servers that ignore Range requests (python -m
    // http.server) would leave the browser unable to seek in it
    const response = await fetch(config.audio);
    if (!response.ok) throw new Error(`cannot load ${config.audio}: HTTP ${response.status}`);
    audio.src = URL.createObjectURL(await response.blob());
    await new Promise((resolve, reject) => {
      if (audio.readyState >= 1) resolve();
      audio.addEventListener('loadedmetadata', resolve, { once: true });
      audio.addEventListener('error', () => reject(new Error(`cannot play ${config.audio}`)),
        { once: true });
    });
    duration = Math.max(duration, audio.duration || 0);
  }
  const clock = new Clock(audio, duration);
  if (audio !== null) audio.addEventListener('ended', () => clock.audioEnded());

  const controls = new OrbitControls(camera, renderer.domElement);
  controls.enableDamping = false;
  function resetView() {
    camera.position.copy(home.position);
    camera.quaternion.copy(home.quaternion);
    controls.target.copy(homeTarget);
    controls.update();
    camera.position.copy(home.position);
    camera.quaternion.copy(home.quaternion);
    changed = true;
  }
  let changed = true;
  controls.addEventListener('change', () => { changed = true; });

  function resize() {
    const w = window.innerWidth;
    const h = window.innerHeight;
    renderer.setSize(w, h, false);
    fitCamera(camera, design.aspect, design.fov, w, h);
    changed = true;
  }
  window.addEventListener('resize', resize);
  resize();
  resetView();

  // ---- controls ----
  const bar = $('bar');
  const slider = $('time');
  const playButton = $('play');
  slider.max = String(duration);
  slider.step = 'any';
  const format = (t) => {
    const m = Math.floor(t / 60);
    return `${m}:${(t - 60 * m).toFixed(2).padStart(5, '0')}`;
  };
  const still = query.get('paused') === '1';
  let hideTimer = 0;
  function showBar() {
    bar.classList.remove('hidden');
    clearTimeout(hideTimer);
    hideTimer = setTimeout(() => { if (clock.playing) bar.classList.add('hidden'); }, 2500);
  }
  if (!still) bar.classList.remove('hidden');
  for (const type of ['pointermove', 'pointerdown', 'keydown']) {
    window.addEventListener(type, showBar);
  }

  async function play() {
    try {
      await clock.play();
      $('message').textContent = '';
      showBar(); // hidden a moment after playing starts, back when the pointer moves
    } catch (e) {
      // browsers play sound only after the user has done something on the page
      $('message').textContent = 'press ▶ to play';
    }
    changed = true;
  }
  function pause() { clock.pause(); changed = true; }
  function toggle() { if (clock.playing) pause(); else play(); }
  function seek(t) { clock.seek(t); changed = true; }
  playButton.addEventListener('click', toggle);
  slider.addEventListener('input', () => seek(Number(slider.value)));
  $('view').addEventListener('click', resetView);
  window.addEventListener('keydown', (e) => {
    // the menu and the buttons have keys of their own (space presses a focused button)
    if (e.target instanceof HTMLSelectElement || e.target instanceof HTMLButtonElement) return;
    const step = config.fps ? 1 / config.fps : 1 / 30;
    if (e.key === ' ') toggle();
    else if (e.key === 'ArrowRight') { pause(); seek(clock.time() + step); }
    else if (e.key === 'ArrowLeft') { pause(); seek(clock.time() - step); }
    else if (e.key === 'Home') seek(0);
    else if (e.key === 'r') resetView();
    else return;
    e.preventDefault();
  });

  // ---- several heads: all of them, or one ----
  const names = heads.map((h, i) => (config.heads && config.heads[i]) || h.name || `head ${i + 1}`);
  const select = $('heads');
  function showHead(index) {
    heads.forEach((h, i) => { h.visible = index < 0 || i === index; });
    select.value = String(index);
    if (index >= 0) {
      // look at that head from where the camera is, near enough for it to fill 80 % of the
      // view as vtts frames a single head
      const box = new THREE.Box3().setFromObject(heads[index]);
      const centre = box.getCenter(new THREE.Vector3());
      const size = box.getSize(new THREE.Vector3());
      const back = camera.position.clone().sub(controls.target).normalize();
      const tanHalf = Math.tan(THREE.MathUtils.degToRad(camera.fov) / 2);
      const half = Math.max(size.y / 2, size.x / 2 / camera.aspect);
      controls.target.copy(centre);
      camera.position.copy(centre).addScaledVector(back, half / (0.8 * tanHalf) + size.z / 2);
      controls.update();
    } else {
      resetView();
    }
    changed = true;
  }
  if (heads.length > 1) {
    select.hidden = false;
    select.add(new Option('all heads', '-1'));
    names.forEach((name, i) => select.add(new Option(name, String(i))));
    select.addEventListener('change', () => showHead(Number(select.value)));
    const wanted = query.get('head');
    if (wanted !== null) {
      const byName = names.indexOf(wanted);
      const index = byName >= 0 ? byName : Number(wanted) - 1;
      if (Number.isInteger(index) && index >= 0 && index < heads.length) showHead(index);
    }
  }

  // ---- drawing ----
  let shownTime = -1;
  let framesDrawn = 0;
  function poseAt(t) {
    for (const action of actions) {
      action.enabled = true;
      action.paused = false;
      action.time = Math.min(t, action.getClip().duration);
    }
    mixer.update(0);
    for (const entry of morphs) applyMorph(entry);
  }
  function frame() {
    const t = clock.time();
    if (t !== shownTime || changed) {
      poseAt(t);
      renderer.render(scene, camera);
      framesDrawn += 1;
      shownTime = t;
      changed = false;
      slider.value = String(t);
      $('clock').textContent = `${format(t)} / ${format(duration)}`;
      playButton.textContent = clock.playing ? '❚❚' : '▶';
    }
    requestAnimationFrame(frame);
  }

  window.vttsPlayer = {
    play, pause, seek, resetView, showHead,
    time: () => clock.time(),
    clockSource: () => clock.source(),
    get duration() { return duration; },
    get framesDrawn() { return framesDrawn; },
    get playing() { return clock.playing; },
  };

  $('message').textContent = '';
  seek(Number(query.get('t')) || 0);
  frame();
  if (still) {
    // "ready" once the frame is on screen (two animation frames: drawn, then composited)
    requestAnimationFrame(() => requestAnimationFrame(() => { document.title = 'ready'; }));
  } else {
    play();
  }
}

main().catch(fail);
