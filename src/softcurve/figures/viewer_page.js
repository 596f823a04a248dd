
(function () {
  "use strict";
  const D = JSON.parse(document.getElementById("softcurve-scene").textContent);
  const COLOURS = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd",
                   "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"];
  const RIGID = "#555555";
  const STRIPE = "#111111";
  const SIDES = 20;
  const bytes = Uint8Array.from(atob(D.rings), (c) => c.charCodeAt(0));
  const rings = new Float32Array(bytes.buffer);
  const F = D.frames, R = D.ringsPerFrame, K = D.ringsPerSegment, N = D.radii.length;
  const plot = document.getElementById("plot");
  const slider = document.getElementById("slider");
  const label = document.getElementById("label");
  const button = document.getElementById("play");
  const speed = document.getElementById("speed");

  function ring(f, r, k) { return rings[(f * R + r) * 9 + k]; }

  function offset(f, r, radius, angle, out) {
    const c = Math.cos(angle) * radius, s = Math.sin(angle) * radius;
    for (let k = 0; k < 3; k++)
      out[k].push(ring(f, r, k) + c * ring(f, r, 3 + k) + s * ring(f, r, 6 + k));
  }

  function tube(f, segment) {
    const out = [[], [], []];
    for (let r = segment * K; r < (segment + 1) * K; r++)
      for (let a = 0; a < SIDES; a++) offset(f, r, D.radii[segment], 2 * Math.PI * a / SIDES, out);
    for (const r of [segment * K, (segment + 1) * K - 1])
      for (let k = 0; k < 3; k++) out[k].push(ring(f, r, k));
    return out;
  }

  function faces() {
    const I = [], J = [], L = [];
    for (let r = 0; r + 1 < K; r++)
      for (let a = 0; a < SIDES; a++) {
        const b = (a + 1) % SIDES, p = r * SIDES, n = p + SIDES;
        I.push(p + a, p + b); J.push(n + a, n + a); L.push(p + b, n + b);
      }
    for (let a = 0; a < SIDES; a++) {
      const b = (a + 1) % SIDES, top = (K - 1) * SIDES;
      I.push(K * SIDES, K * SIDES + 1); J.push(a, top + a); L.push(b, top + b);
    }
    return [I, J, L];
  }

  function tendon(f, t) {
    const out = [[], [], []];
    for (let r = 0; r < t.rings; r++) offset(f, r, t.distance, t.azimuth, out);
    return out;
  }

  function stripe(f, segment) {
    const out = [[], [], []];
    for (let r = segment * K; r < (segment + 1) * K; r++) offset(f, r, 1.02 * D.radii[segment], 0, out);
    return out;
  }
  const soft = [], stripes = [];
  for (let s = 0; s < N; s++) if (D.kinds[s] === "soft") soft.push(s);
  if (D.stripes) stripes.push(...soft);

  function tip(f) { return [[ring(f, R - 1, 0)], [ring(f, R - 1, 1)], [ring(f, R - 1, 2)]]; }

  const traces = [], moving = [];
  const [I, J, L] = faces();
  const opacity = D.tendons.length ? 0.45 : 1.0;
  for (let s = 0; s < N; s++) {
    const [x, y, z] = tube(0, s);
    const rigid = D.kinds[s] === "rigid";
    moving.push(traces.length);
    traces.push({type: "mesh3d", x: x, y: y, z: z, i: I, j: J, k: L,
                 color: rigid ? RIGID : COLOURS[soft.indexOf(s) % 10],
                 opacity: opacity, flatshading: false,
                 name: (rigid ? "rigid body " : "segment ") + (s + 1),
                 showlegend: true, hoverinfo: "name", lighting: {ambient: 0.55, diffuse: 0.7}});
  }
  stripes.forEach((s, n) => {
    const [x, y, z] = stripe(0, s);
    moving.push(traces.length);
    traces.push({type: "scatter3d", mode: "lines", x: x, y: y, z: z, name: "stripe (twist)",
                 legendgroup: "stripe", showlegend: n === 0, hoverinfo: "name",
                 line: {color: STRIPE, width: 5}});
  });
  D.tendons.forEach((t, n) => {
    const [x, y, z] = tendon(0, t);
    moving.push(traces.length);
    traces.push({type: "scatter3d", mode: "lines", x: x, y: y, z: z, name: "tendon " + (n + 1),
                 line: {color: "#222222", width: 4}, hoverinfo: "name"});
  });
  const [tx, ty, tz] = tip(0);
  moving.push(traces.length);
  traces.push({type: "scatter3d", mode: "markers", x: tx, y: ty, z: tz, name: "tip",
               marker: {size: 4, color: "#d62728"}, hoverinfo: "name"});
  if (D.tipPath.length)
    traces.push({type: "scatter3d", mode: "lines", name: "tip path", hoverinfo: "skip",
                 x: D.tipPath.map((p) => p[0]), y: D.tipPath.map((p) => p[1]),
                 z: D.tipPath.map((p) => p[2]), line: {color: "#888888", width: 2}});
  ["x", "y", "z"].forEach((axis, k) => {
    const end = [0, 0, 0]; end[k] = D.baseAxes;
    traces.push({type: "scatter3d", mode: "lines+text", x: [0, end[0]], y: [0, end[1]],
                 z: [0, end[2]], text: ["", axis], textfont: {color: ["#c00", "#080", "#00c"][k]},
                 line: {color: ["#c00", "#080", "#00c"][k], width: 5},
                 name: "base " + axis, showlegend: false, hoverinfo: "name"});
  });
  D.obstacles.forEach((o, n) => traces.push({
    type: "mesh3d", name: "obstacle " + (n + 1), color: "#999999", opacity: 0.6,
    x: o.vertices.map((v) => v[0]), y: o.vertices.map((v) => v[1]),
    z: o.vertices.map((v) => v[2]), i: o.triangles.map((t) => t[0]),
    j: o.triangles.map((t) => t[1]), k: o.triangles.map((t) => t[2]),
    showlegend: true, hoverinfo: "name"}));

  const axis = (name, k) => ({title: {text: name + " [mm]"}, range: D.bounds[k], autorange: false});
  const layout = {
    margin: {l: 0, r: 0, t: 0, b: 0}, uirevision: "keep", legend: {x: 0, y: 1},
    scene: {aspectmode: "cube", xaxis: axis("x", 0), yaxis: axis("y", 1), zaxis: axis("z", 2),
            camera: {eye: {x: 1.5, y: -1.5, z: 0.9}}},
  };

  let current = 0, playing = false, clock = 0, last = null, busy = Promise.resolve();
  function draw(f) {
    const update = {x: [], y: [], z: []};
    const add = (p) => { update.x.push(p[0]); update.y.push(p[1]); update.z.push(p[2]); };
    for (let s = 0; s < N; s++) add(tube(f, s));
    for (const s of stripes) add(stripe(f, s));
    for (const t of D.tendons) add(tendon(f, t));
    add(tip(f));
    return Plotly.restyle(plot, update, moving)
      .then(() => { document.body.dataset.frame = String(f); });
  }
  function show(f) {
    current = Math.max(0, Math.min(F - 1, Math.round(f)));
    slider.value = current;
    label.textContent = D.labels[current];
    busy = busy.then(() => draw(current));
    return busy;
  }
  function frameAt(time) {
    let f = 0;
    while (f + 1 < F && D.times[f + 1] <= time) f++;
    return f;
  }
  function tick(now) {
    if (!playing) return;
    if (last !== null) clock += (now - last) / 1000 * Number(speed.value);
    last = now;
    const f = frameAt(clock);
    const done = clock >= D.times[F - 1];
    (f !== current ? show(f) : busy).then(() => {
      if (done) pause(); else requestAnimationFrame(tick);
    });
  }
  function play() {
    if (!D.times || F < 2) return;
    if (current >= F - 1) show(0);
    clock = D.times[current]; last = null; playing = true;
    button.textContent = "Pause";
    requestAnimationFrame(tick);
  }
  function pause() { playing = false; button.textContent = "Play"; }

  button.addEventListener("click", () => (playing ? pause() : play()));
  slider.addEventListener("input", () => { pause(); show(Number(slider.value)); });
  slider.max = F - 1;
  if (!D.times || F < 2) { button.hidden = true; speed.hidden = true; }
  if (F < 2) slider.hidden = true;

  let first = 0;
  const wanted = new URLSearchParams(location.hash.slice(1));
  if (wanted.has("frame")) first = Number(wanted.get("frame"));
  else if (wanted.has("t") && D.times) first = frameAt(Number(wanted.get("t")));
  window.softcurveViewer = {show: show, play: play, pause: pause, frames: F};
  busy = Plotly.newPlot(plot, traces, layout, {displaylogo: false, responsive: true});
  show(first);
})();
