// The page `freeform view` writes: plays a run's frames with three.js (bundled in
// `vendor/three-subset.js` as the global `FreeFormThree`). The frames arrive as one base64 blob
// of little-endian float32 / uint32 arrays whose offsets (in 4-byte words) `freeform-meta`
// lists; see `cli/src/viewer_page.rs` for the layout.
"use strict";

(async function main() {
  const T = window.FreeFormThree;
  const meta = JSON.parse(document.getElementById("freeform-meta").textContent);
  const base64 = document.getElementById("freeform-data").textContent.trim();
  const bytes = await (await fetch("data:application/octet-stream;base64," + base64)).arrayBuffer();
  const f32 = (offset, length) => new Float32Array(bytes, 4 * offset, length);
  const u32 = (offset, length) => new Uint32Array(bytes, 4 * offset, length);

  // Viridis, linearly interpolated between its quartiles (matplotlib's sRGB values); three.js
  // takes vertex colours as linear RGB, so they are converted.
  const VIRIDIS = [[0x44, 0x01, 0x54], [0x3b, 0x52, 0x8b], [0x21, 0x91, 0x8c], [0x5e, 0xc9, 0x62], [0xfd, 0xe7, 0x25]];
  function viridis(t) {
    const s = Math.min(Math.max(t, 0), 1) * (VIRIDIS.length - 1);
    const i = Math.min(Math.floor(s), VIRIDIS.length - 2);
    const a = VIRIDIS[i], b = VIRIDIS[i + 1], w = s - i;
    return [0, 1, 2].map((k) => srgbToLinear((a[k] + (b[k] - a[k]) * w) / 255));
  }
  function srgbToLinear(c) {
    return c <= 0.04045 ? c / 12.92 : Math.pow((c + 0.055) / 1.055, 2.4);
  }

  const container = document.getElementById("view");
  const renderer = new T.WebGLRenderer({ antialias: true, preserveDrawingBuffer: true });
  renderer.setPixelRatio(window.devicePixelRatio);
  renderer.setSize(container.clientWidth, container.clientHeight);
  renderer.setClearColor(0xf4f5f7);
  container.appendChild(renderer.domElement);

  const scene = new T.Scene();
  const up = new T.Vector3(...meta.up);
  const lo = new T.Vector3(...meta.bounds.min), hi = new T.Vector3(...meta.bounds.max);
  const centre = lo.clone().add(hi).multiplyScalar(0.5);
  const radius = Math.max(0.5 * hi.clone().sub(lo).length(), 1e-6);
  const camera = new T.PerspectiveCamera(40, container.clientWidth / container.clientHeight, radius / 100, radius * 100);
  camera.up.copy(up);
  // 30° about and 20° above the up direction, as the preview looks.
  const side = Math.abs(up.x) < 0.9 ? new T.Vector3(1, 0, 0) : new T.Vector3(0, 1, 0);
  const e0 = side.clone().sub(up.clone().multiplyScalar(up.dot(side))).normalize();
  const e1 = up.clone().cross(e0);
  const az = (30 * Math.PI) / 180, el = (20 * Math.PI) / 180;
  const direction = e0.clone().multiplyScalar(Math.cos(az) * Math.cos(el))
    .add(e1.clone().multiplyScalar(Math.sin(az) * Math.cos(el)))
    .add(up.clone().multiplyScalar(Math.sin(el)));
  camera.position.copy(centre).add(direction.multiplyScalar((1.3 * radius) / Math.sin((20 * Math.PI) / 180)));
  const controls = new T.OrbitControls(camera, renderer.domElement);
  controls.target.copy(centre);
  controls.update();

  scene.add(new T.HemisphereLight(0xffffff, 0x777777, 1.6));
  const headlight = new T.DirectionalLight(0xffffff, 1.4);
  headlight.position.set(0.3, 1, 0.5);
  camera.add(headlight);
  scene.add(camera);

  if (meta.floor) {
    const normal = new T.Vector3(...meta.floor.normal);
    const origin = centre.clone().sub(normal.clone().multiplyScalar(normal.dot(centre) - meta.floor.offset));
    const size = 6 * radius;
    const turn = new T.Quaternion().setFromUnitVectors(new T.Vector3(0, 1, 0), normal);
    const plane = new T.Mesh(new T.PlaneGeometry(size, size).rotateX(-Math.PI / 2),
      new T.MeshLambertMaterial({ color: 0xdddddd, side: T.DoubleSide }));
    const grid = new T.GridHelper(size, 24, 0x999999, 0xbbbbbb);
    for (const [object, lift] of [[plane, -1e-4], [grid, 1e-4]]) {
      object.quaternion.copy(turn);
      object.position.copy(origin).add(normal.clone().multiplyScalar(lift * radius));
      scene.add(object);
    }
  }

  const scalars = meta.scalars;
  const select = document.getElementById("scalar");
  const choices = scalars.map((s) => s.label);
  if (meta.objects.some((o) => o.colours !== null)) choices.push("splat colour");
  for (const [i, label] of choices.entries()) select.add(new Option(label, String(i)));

  const frames = meta.frames;
  const objects = meta.objects.map((o) => {
    const geometry = new T.BufferGeometry();
    const position = new T.BufferAttribute(new Float32Array(3 * o.points), 3);
    position.setUsage(T.DynamicDrawUsage);
    const colour = new T.BufferAttribute(new Float32Array(3 * o.points), 3);
    geometry.setAttribute("position", position);
    geometry.setAttribute("color", colour);
    let drawn;
    if (o.triangles !== null) {
      geometry.setIndex(new T.BufferAttribute(u32(o.triangles.offset, 3 * o.triangles.count), 1));
      drawn = new T.Mesh(geometry, new T.MeshLambertMaterial({ vertexColors: true, side: T.DoubleSide }));
    } else {
      const spacing = (2 * radius) / Math.cbrt(Math.max(o.points, 1));
      drawn = new T.Points(geometry, new T.PointsMaterial({ vertexColors: true, size: 0.8 * spacing }));
    }
    drawn.name = o.name;
    scene.add(drawn);
    return { meta: o, geometry, position, colour, drawn };
  });

  const colliderGeometry = new T.BufferGeometry();
  const colliderMesh = new T.Mesh(colliderGeometry, new T.MeshLambertMaterial({
    color: 0x6f9fd8, transparent: true, opacity: 0.35, side: T.DoubleSide, depthWrite: false }));
  colliderMesh.renderOrder = 1;
  scene.add(colliderMesh);

  const slider = document.getElementById("frame");
  slider.max = String(frames.length - 1);
  const timeLabel = document.getElementById("time");
  document.getElementById("title").textContent = meta.title;
  document.getElementById("notes").textContent = meta.notes.join(" ");

  function drawLegend(choice) {
    const bar = document.getElementById("colour-bar");
    const ticks = document.getElementById("ticks");
    const unit = document.getElementById("legend-unit");
    const g = bar.getContext("2d");
    ticks.replaceChildren();
    bar.style.display = choice >= scalars.length ? "none" : "";
    if (choice >= scalars.length) {
      unit.textContent = "the splats' own colours";
      return;
    }
    for (let y = 0; y < bar.height; y++) {
      // The bar is drawn in sRGB, as the page is.
      const [r, gr, b] = viridis(1 - y / (bar.height - 1)).map((c) => c <= 0.0031308 ? 12.92 * c : 1.055 * Math.pow(c, 1 / 2.4) - 0.055);
      g.fillStyle = `rgb(${255 * r},${255 * gr},${255 * b})`;
      g.fillRect(0, y, bar.width, 1);
    }
    const s = scalars[choice];
    for (const t of [1, 0.75, 0.5, 0.25, 0]) {
      const tick = document.createElement("div");
      tick.textContent = (t === 1 && s.clipped ? "≥ " : "") + (t * s.max).toPrecision(3);
      ticks.appendChild(tick);
    }
    unit.textContent = `${s.label} (${s.unit})`;
  }

  let current = -1;
  function setFrame(k, force = false) {
    k = Math.min(Math.max(Math.round(k), 0), frames.length - 1);
    if (k === current && !force) return;
    current = k;
    const choice = Number(select.value || 0);
    for (const o of objects) {
      o.position.array.set(f32(o.meta.positions[k], 3 * o.meta.points));
      o.position.needsUpdate = true;
      const out = o.colour.array;
      if (choice < scalars.length) {
        const values = f32(o.meta.scalars[scalars[choice].key][k], o.meta.points);
        const max = scalars[choice].max > 0 ? scalars[choice].max : 1;
        for (let i = 0; i < o.meta.points; i++) out.set(viridis(values[i] / max), 3 * i);
      } else if (o.meta.colours !== null) {
        out.set(f32(o.meta.colours, 3 * o.meta.points));
      } else {
        out.fill(0.7);
      }
      o.colour.needsUpdate = true;
      if (o.meta.triangles !== null) o.geometry.computeVertexNormals();
      o.geometry.computeBoundingSphere();
    }
    const c = meta.colliders[k];
    colliderMesh.visible = c !== null;
    if (c !== null) {
      colliderGeometry.setAttribute("position", new T.BufferAttribute(f32(c.positions, 3 * c.vertices).slice(), 3));
      colliderGeometry.setIndex(new T.BufferAttribute(u32(c.triangles, 3 * c.count).slice(), 1));
      colliderGeometry.computeVertexNormals();
      colliderGeometry.computeBoundingSphere();
    }
    slider.value = String(k);
    const time = meta.time_step === null ? "" : ` · t = ${(frames[k] * meta.time_step).toFixed(3)} s`;
    timeLabel.textContent = `frame ${k + 1} of ${frames.length} (step ${frames[k]})${time}`;
    document.body.dataset.frame = String(k);
  }

  let playing = false, last = 0;
  const play = document.getElementById("play");
  play.addEventListener("click", () => {
    playing = !playing;
    play.textContent = playing ? "Pause" : "Play";
    if (playing && current === frames.length - 1) setFrame(0);
  });
  slider.addEventListener("input", () => setFrame(Number(slider.value)));
  select.addEventListener("change", () => { drawLegend(Number(select.value)); setFrame(current, true); });
  window.addEventListener("resize", () => {
    camera.aspect = container.clientWidth / container.clientHeight;
    camera.updateProjectionMatrix();
    renderer.setSize(container.clientWidth, container.clientHeight);
  });

  // Splats open in their own colours, everything else in the first scalar.
  const splats = meta.objects.every((o) => o.colours !== null);
  select.value = splats ? String(scalars.length) : "0";
  drawLegend(Number(select.value));
  setFrame(0, true);
  renderer.setAnimationLoop((now) => {
    if (playing && now - last > 50) {
      last = now;
      if (current + 1 < frames.length) setFrame(current + 1);
      else { playing = false; play.textContent = "Play"; }
    }
    controls.update();
    renderer.render(scene, camera);
    if (document.body.dataset.ready !== "1") document.body.dataset.ready = "1";
  });
  window.freeformViewer = { setFrame, frameCount: frames.length };
})().catch((error) => {
  document.getElementById("notes").textContent = "The viewer failed: " + error;
  document.body.dataset.error = String(error);
});
