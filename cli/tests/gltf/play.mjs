// Plays a glTF/GLB file with three.js under Node.js and writes the world-space vertex
// positions of every frame, for cli/tests/gltf.rs to compare with animcodec's own glTF reader.
//
//   node play.mjs FILE.glb OUT.f32 --animation INDEX --t0 T0 --fps FPS --frames N
//
// The file is parsed with three's GLTFLoader (EXT_meshopt_compression through three's
// MeshoptDecoder), the animation is run with an AnimationMixer (LoopOnce, one action at
// weight 1) at t = t0 + k / fps for k < N (rounded to f32 like the key times), and every
// mesh's vertices are taken with Mesh.getVertexPosition (morph targets, then
// SkinnedMesh.applyBoneTransform: skinning on the CPU) and placed with matrixWorld. Meshes are
// visited in scene.traverse order, which for GLTFLoader's scene is animcodec's documented
// vertex order (scene root nodes in order, depth first, a node's mesh/primitives before its
// children). OUT.f32: N × V × 3 little-endian float32. Prints {"vertices": V, "frames": N,
// "meshes": M} on stdout. With --frames 0: no animation, one frame at rest.
import { readFileSync, writeFileSync } from 'node:fs';
import { AnimationMixer, LoopOnce, Vector3 } from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';
import { MeshoptDecoder } from 'three/examples/jsm/libs/meshopt_decoder.module.js';
import { DRACOLoader } from 'three/examples/jsm/loaders/DRACOLoader.js';
import { resolveObjectURL } from 'node:buffer';
import { Worker as ThreadWorker } from 'node:worker_threads';
import { fileURLToPath } from 'node:url';
import { dirname, join } from 'node:path';

// three's FileLoader (used for a .gltf's data: URI buffer) reports progress with the DOM's
// ProgressEvent, which Node.js lacks.
globalThis.ProgressEvent ??= class ProgressEvent extends Event {
  constructor(type, init = {}) {
    super(type);
    Object.assign(this, init);
  }
};

// KHR_draco_mesh_compression: three's DRACOLoader with the Draco decoder three ships
// (examples/jsm/libs/draco, Google's WebAssembly build). The loader runs the decoder in a Web
// Worker made from a blob: URL and fetches the decoder files; Node.js has neither Web Workers
// nor file fetches, so the decoder files are read from disk and the worker runs in a
// worker_threads thread with the DOM worker globals (self, onmessage, postMessage) it expects.
const dracoDir = join(dirname(fileURLToPath(import.meta.url)), 'node_modules/three/examples/jsm/libs/draco');
DRACOLoader.prototype._loadLibrary = function (url, responseType) {
  const data = readFileSync(join(dracoDir, url.split('/').pop()));
  return Promise.resolve(responseType === 'text' ? data.toString('utf8') : data.buffer.slice(data.byteOffset, data.byteOffset + data.byteLength));
};
globalThis.Worker ??= class Worker {
  constructor(url) {
    this.onmessage = null;
    this.pending = resolveObjectURL(url).text().then((body) => {
      const prelude = `const { parentPort } = require('node:worker_threads');
        globalThis.self = globalThis;
        globalThis.postMessage = (message, transfer) => parentPort.postMessage(message, transfer);
        parentPort.on('message', (data) => globalThis.onmessage({ data }));\n`;
      this.thread = new ThreadWorker(prelude + body, { eval: true });
      this.thread.on('message', (data) => this.onmessage && this.onmessage({ data }));
      this.thread.on('error', (e) => { throw e; });
      return this.thread;
    });
  }
  postMessage(message, transfer) {
    this.pending.then((thread) => thread.postMessage(message, transfer));
  }
  terminate() {
    this.pending.then((thread) => thread.terminate());
  }
};

const [file, out, ...rest] = process.argv.slice(2);
const opt = {};
for (let i = 0; i < rest.length; i += 2) opt[rest[i].replace(/^--/, '')] = rest[i + 1];
const data = readFileSync(file);
const buffer = data.buffer.slice(data.byteOffset, data.byteOffset + data.byteLength);

await MeshoptDecoder.ready;
const loader = new GLTFLoader();
loader.setMeshoptDecoder(MeshoptDecoder);
const dracoLoader = new DRACOLoader().setDecoderPath('draco/');
loader.setDRACOLoader(dracoLoader);
const gltf = await new Promise((resolve, reject) => loader.parse(buffer, '', resolve, reject));

const scene = gltf.scene;
const meshes = [];
scene.traverse((o) => { if (o.isMesh) meshes.push(o); });
const vertices = meshes.reduce((n, m) => n + m.geometry.attributes.position.count, 0);

const frames = Math.max(1, Number(opt.frames ?? 1));
const fps = Number(opt.fps ?? 30);
const t0 = Number(opt.t0 ?? 0);
let mixer = null;
let action = null;
if (opt.animation !== undefined && Number(opt.frames ?? 0) > 0) {
  const clip = gltf.animations[Number(opt.animation)];
  if (!clip) throw new Error(`no animation ${opt.animation}`);
  // NORMALIZE_ROTATIONS=1: every rotation key is normalized before playing, as animcodec's
  // reader does (glTF rotations are unit quaternions; three.js uses a stored key as it is, and
  // a 16-bit quantized key, as gltfpack writes, is unit only to about 1e-4).
  if (process.env.NORMALIZE_ROTATIONS === '1') {
    for (const track of clip.tracks) {
      if (!track.name.endsWith('.quaternion')) continue;
      const v = track.values;
      for (let i = 0; i + 4 <= v.length; i += 4) {
        const n = Math.hypot(v[i], v[i + 1], v[i + 2], v[i + 3]);
        if (n > 0) for (let c = 0; c < 4; c++) v[i + c] /= n;
      }
    }
  }
  mixer = new AnimationMixer(scene);
  action = mixer.clipAction(clip);
  action.setLoop(LoopOnce, 1);
  action.clampWhenFinished = true;
}

const positions = new Float32Array(frames * vertices * 3);
const v = new Vector3();
let at = 0;
for (let k = 0; k < frames; k++) {
  if (mixer) {
    action.reset();
    action.play();
    mixer.setTime(Math.fround(t0 + k / fps));
  }
  scene.updateMatrixWorld(true);
  for (const mesh of meshes) {
    const count = mesh.geometry.attributes.position.count;
    for (let i = 0; i < count; i++) {
      mesh.getVertexPosition(i, v);
      v.applyMatrix4(mesh.matrixWorld);
      positions[at++] = v.x;
      positions[at++] = v.y;
      positions[at++] = v.z;
    }
  }
}
writeFileSync(out, Buffer.from(positions.buffer));
dracoLoader.dispose();
console.log(JSON.stringify({ vertices, frames, meshes: meshes.length }));
