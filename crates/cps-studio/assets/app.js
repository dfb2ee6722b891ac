// cps studio: the page. Way points in a 3-D view; dragging a via point re-learns the
// movement with the exact solver on every move and, on release, with the chosen solver.
"use strict";

const state = {
  start: [0.75, 0.02, 1.87],
  goal: [0.55, -0.57, 1.45],
  tau: 10,
  via: [
    { time: 2, position: [0.78, 0.60, 1.70] },
    { time: 4, position: [1.12, 0.37, 1.45] },
    { time: 6, position: [1.15, -0.15, 1.20] },
    { time: 8, position: [0.90, -0.53, 1.20] },
  ],
  weights: { goal: 1e5, via: 1e5, final_velocity: 1e3, acceleration: 1e-2, jerk: 0 },
  path: null,     // the last answer
  learned: 0,     // answers received
  robot: null,    // the robot at rest (GET /api/robot)
  name: "studio", // the experiment's name (from an opened file)
  demoFiles: [],  // uploaded demonstrations: {name, text}
  imitation: null, // the last imitation answer
  frame: -1,      // the robot pose shown (index into path.robot.frames; -1: the last)
};
const view = { yaw: -0.6, pitch: 0.45, zoom: 0.7, center: [0.8, 0.0, 1.3] };
const canvas = document.getElementById("canvas");
const ctx = canvas.getContext("2d");
// The robot's and the scene's shapes, under the overlay (scene.js); set once /api/robot
// answers with shapes and the browser has WebGL.
const glCanvas = document.getElementById("gl");

// ---------------------------------------------------------------- projection
function rotate(p) {
  const x = p[0] - view.center[0], y = p[1] - view.center[1], z = p[2] - view.center[2];
  const cy = Math.cos(view.yaw), sy = Math.sin(view.yaw);
  const x1 = cy * x - sy * y, y1 = sy * x + cy * y;
  const cp = Math.cos(view.pitch), sp = Math.sin(view.pitch);
  // screen right = x1, screen up = cp * z + sp * y1, depth = cp * y1 - sp * z
  return [x1, cp * z + sp * y1, cp * y1 - sp * z];
}
function scale() {
  return 0.8 * Math.min(canvas.width, canvas.height) * view.zoom;
}
function project(p) {
  const r = rotate(p), s = scale();
  return [canvas.width / 2 + s * r[0], canvas.height / 2 - s * r[1]];
}
// A screen displacement as a world displacement in the view plane.
function unproject(dx, dy) {
  const s = scale(), right = dx / s, up = -dy / s;
  const cy = Math.cos(view.yaw), sy = Math.sin(view.yaw);
  const cp = Math.cos(view.pitch), sp = Math.sin(view.pitch);
  // inverse of rotate for (right, up, 0)
  const y1 = sp * up, z = cp * up, x1 = right;
  return [cy * x1 + sy * y1, -sy * x1 + cy * y1, z];
}

// ---------------------------------------------------------------- drawing
function resize() {
  const r = canvas.getBoundingClientRect();
  canvas.width = Math.max(100, Math.round(r.width * devicePixelRatio));
  canvas.height = Math.max(100, Math.round(r.height * devicePixelRatio));
  glCanvas.width = canvas.width;
  glCanvas.height = canvas.height;
  draw();
}
function line(points, color, width) {
  ctx.strokeStyle = color;
  ctx.lineWidth = width * devicePixelRatio;
  ctx.beginPath();
  points.forEach((p, i) => {
    const s = project(p);
    if (i === 0) ctx.moveTo(s[0], s[1]); else ctx.lineTo(s[0], s[1]);
  });
  ctx.stroke();
}
function marker(p, color, label, square) {
  const s = project(p), r = 6 * devicePixelRatio;
  ctx.fillStyle = color;
  ctx.beginPath();
  if (square) ctx.rect(s[0] - r, s[1] - r, 2 * r, 2 * r); else ctx.arc(s[0], s[1], r, 0, 2 * Math.PI);
  ctx.fill();
  ctx.fillStyle = "#222";
  ctx.font = `${12 * devicePixelRatio}px system-ui`;
  ctx.fillText(label, s[0] + 1.5 * r, s[1] - r);
}
// The floor: at the robot's base (or below the lowest way point).
function floorHeight() {
  const zs = [state.start[2], state.goal[2], ...state.via.map(v => v.position[2])];
  return state.robot ? state.robot.points[0][2] : Math.min(...zs) - 0.1;
}
// The drawn pose's index into the executed frames, or null before a movement is executed.
function shownFrame() {
  const r = state.path && state.path.robot;
  if (!(r && r.frames.length)) return null;
  return state.frame < 0 ? r.frames.length - 1 : Math.min(state.frame, r.frames.length - 1);
}
// A redraw at the next frame, however many moves ask for one before it.
let drawQueued = false;
function drawSoon() {
  if (drawQueued) return;
  drawQueued = true;
  requestAnimationFrame(() => { drawQueued = false; draw(); });
}
function draw() {
  ctx.clearRect(0, 0, canvas.width, canvas.height);
  const floor = floorHeight();
  const solid = Scene3D.active;
  if (solid) {
    // The shapes at the shown pose, its near pairs coloured (WebGL, under this overlay).
    const r = state.path && state.path.robot, k = shownFrame();
    const posed = k !== null && r.poses && r.poses.length;
    const coloured = Scene3D.draw(view, scale(), posed ? r.poses[k] : state.robot.pose,
      posed ? r.near[k] : [], state.robot.shapes.margin);
    document.body.dataset.coloured = coloured.join(",");
  } else {
    // A floor grid, 10 cm squares.
    for (let i = -10; i <= 10; i++) {
      const a = view.center[0] + i * 0.1, b = view.center[1] + i * 0.1;
      line([[a, view.center[1] - 1, floor], [a, view.center[1] + 1, floor]], "#eee", 1);
      line([[view.center[0] - 1, b, floor], [view.center[0] + 1, b, floor]], "#eee", 1);
    }
  }
  const o = [view.center[0] - 1, view.center[1] - 1, floor];
  line([o, [o[0] + 0.2, o[1], o[2]]], "#d33", 2);
  line([o, [o[0], o[1] + 0.2, o[2]]], "#3a3", 2);
  line([o, [o[0], o[1], o[2] + 0.2]], "#33d", 2);
  const im = state.imitation;
  if (im && im.names.length === 3) {
    for (const d of im.demos) line(d.values, "#bbb", 1);
    if (im.promp) line(im.promp.mean, "#8e44ad", 1.5);
    line(im.dmp.values, "#e67e22", 2.5);
  }
  if (state.path) line(state.path.position, "#1f5fbf", 2.5);
  const executed = state.path && state.path.robot;
  if (executed && executed.tool.length) line(executed.tool, "#2a9d4b", 1.2);
  const frames = executed && executed.frames.length ? executed.frames : null;
  const pose = frames ? frames[shownFrame()] : state.robot && state.robot.points;
  if (pose && !solid) {
    line(pose, "#777", 7);
    for (const p of pose) {
      const s = project(p);
      ctx.fillStyle = "#333";
      ctx.beginPath();
      ctx.arc(s[0], s[1], 3.5 * devicePixelRatio, 0, 2 * Math.PI);
      ctx.fill();
    }
  }
  marker(state.start, "#444", "start", true);
  marker(state.goal, "#444", "goal", true);
  const out = executed && executed.unreachable ? executed.unreachable.split("`")[1] : null;
  state.via.forEach((v, i) => marker(v.position, dragging === i ? "#f80" : out === `via[${i}]` ? "#b00020" : "#e0457b", `p${i + 1}`, false));
}

// ---------------------------------------------------------------- the side panel
const fmt = (x, d) => Number(x).toFixed(d);
function pointRows() {
  const body = document.querySelector("#points tbody");
  body.innerHTML = "";
  const rows = [["start", null, state.start], ...state.via.map((v, i) => [`p${i + 1}`, v, v.position]), ["goal", null, state.goal]];
  rows.forEach(([name, via, p], r) => {
    const tr = document.createElement("tr");
    const cell = html => { const td = document.createElement("td"); td.append(html); tr.append(td); };
    cell(name);
    if (via) {
      const t = number(via.time, 0.1, value => { via.time = value; });
      t.dataset.field = `via[${r - 1}].time`;
      cell(t);
    } else cell(name === "goal" ? `${state.tau}` : "0");
    for (let d = 0; d < 3; d++) {
      const input = number(p[d], 0.01, value => { p[d] = value; draw(); });
      input.dataset.field = via ? `via[${r - 1}].position` : name;
      cell(input);
    }
    body.append(tr);
  });
}
function number(value, step, set) {
  const input = document.createElement("input");
  input.type = "number";
  input.step = step;
  input.setAttribute("value", fmt(value, 3));
  input.addEventListener("change", () => {
    set(Number(input.value));
    learn(document.getElementById("solver").value);
  });
  return input;
}
function weightRows() {
  const body = document.querySelector("#weights tbody");
  body.innerHTML = "";
  for (const name of Object.keys(state.weights)) {
    const tr = document.createElement("tr");
    const label = document.createElement("td");
    label.textContent = name;
    const td = document.createElement("td");
    const input = document.createElement("input");
    input.type = "number";
    input.value = state.weights[name];
    input.dataset.field = `weights.${name}`;
    input.addEventListener("change", () => {
      state.weights[name] = Number(input.value);
      learn(document.getElementById("solver").value);
    });
    td.append(input);
    tr.append(label, td);
    body.append(tr);
  }
}
function showNumbers(answer, millis) {
  const rows = [
    ["solver", answer.solver + (answer.generations ? ` (${answer.generations} generations)` : "")],
    ["cost", answer.cost.toExponential(5)],
    ["exact optimum", answer.optimum_cost.toExponential(5)],
    ...Object.entries(answer.cost_terms).filter(([, v]) => v > 0).map(([k, v]) => [`  ${k} term`, v.toExponential(3)]),
    ["goal error", `${fmt(answer.goal_error_m * 1e3, 3)} mm`],
    ...answer.via_errors_m.map((e, i) => [`p${i + 1} error`, `${fmt(e * 1e3, 3)} mm`]),
    ["learned and drawn in", `${fmt(millis, 1)} ms`],
  ];
  const robot = answer.robot;
  if (robot && !robot.unreachable) {
    rows.splice(rows.length - 1, 0,
      ["robot: worst tracking", `${fmt(robot.max_tracking_error_m * 1e3, 3)} mm`],
      ["robot: samples not reached", `${robot.unconverged}`]);
  }
  document.getElementById("robot-error").textContent = robot && robot.unreachable ? robot.unreachable : "";
  const limits = document.getElementById("limits");
  if (!(robot && robot.limit_usage === null)) { // null while dragging: checked on release
    limits.textContent = robot && robot.limit_lines ? robot.limit_lines.join("\n") : "";
    limits.classList.toggle("violated", Boolean(robot && robot.limit_usage && robot.limit_usage.ok === false));
    const hit = document.getElementById("collision");
    const shapes = state.robot && state.robot.shapes;
    hit.textContent = !robot || robot.unreachable ? ""
      : !shapes ? (state.robot && state.robot.shapes_note) || ""
      : robot.collision ? `refused: ${robot.collision}`
      : `clear: every pair keeps the ${fmt(shapes.margin * 1e3, 1)} mm margin`;
    hit.classList.toggle("hit", Boolean(robot && robot.collision));
  }
  const body = document.querySelector("#numbers tbody");
  body.innerHTML = "";
  for (const [k, v] of rows) {
    const tr = document.createElement("tr");
    tr.innerHTML = "<td></td><td></td>";
    tr.children[0].textContent = k;
    tr.children[1].textContent = v;
    tr.dataset.name = k;
    body.append(tr);
  }
}
// A refusal next to its field: the sentence starts with the field's name.
function showError(sentence) {
  for (const el of document.querySelectorAll(".bad")) el.classList.remove("bad");
  for (const id of ["error", "tau-error", "points-error", "weights-error"]) document.getElementById(id).textContent = "";
  if (!sentence) return;
  const field = sentence.split(":")[0];
  let where = "error";
  if (field.startsWith("tau")) where = "tau-error";
  else if (field.startsWith("via") || field === "start" || field === "goal") where = "points-error";
  else if (field.startsWith("weights")) where = "weights-error";
  document.getElementById(where).textContent = sentence;
  for (const el of document.querySelectorAll(`[data-field^="${CSS.escape(field.replace(/\[\d+\]$/, ""))}"]`)) el.classList.add("bad");
}

// ---------------------------------------------------------------- learning
let inFlight = false, pending = null;
// Latency from a gesture (a move, a release) to its path on screen, per solver: the time
// of the oldest gesture not yet drawn, to the redraw of the answer that includes it.
let gestureAt = null;
const latencies = { exact: [], cmaes: [] };
function gesture() { if (gestureAt === null) gestureAt = performance.now(); }
async function learn(solver) {
  if (inFlight) { pending = solver; return; }
  inFlight = true;
  const started = performance.now();
  const since = gestureAt;
  gestureAt = null;
  const asked = request(solver);
  asked.robot = document.getElementById("robot").checked && state.robot !== null;
  // The limit check at 1 kHz is left out while a point is being dragged.
  asked.limits = dragging === null;
  try {
    const reply = await fetch("/api/viapoint", {
      method: "POST", headers: { "content-type": "application/json" }, body: JSON.stringify(asked),
    });
    const body = await reply.json();
    if (!reply.ok) {
      showError(body.error || `HTTP ${reply.status}`);
    } else {
      state.path = body;
      state.learned += 1;
      state.tau = asked.tau;
      // A movement the guard refuses opens at its first pose within the margin.
      const hits = collisionFrames(body.robot);
      if (body.robot && body.robot.collision && hits.length) state.frame = hits[0];
      player();
      draw();
      showError(null);
      showNumbers(body, performance.now() - started);
      if (since !== null) latencies[solver].push(performance.now() - since);
      document.body.dataset.learned = String(state.learned);
      document.body.dataset.samples = String(body.t.length);
      document.body.dataset.end = body.position[body.position.length - 1].map(v => v.toFixed(4)).join(",");
      document.body.dataset.robotFrames = String(body.robot ? body.robot.frames.length : 0);
      document.body.dataset.collisionFrames = String(hits.length);
      census();
    }
  } catch (e) {
    showError(`the studio did not answer: ${e}`);
  } finally {
    inFlight = false;
    if (pending) { const s = pending; pending = null; learn(s); }
  }
}

// ---------------------------------------------------------------- mouse
let dragging = null, orbit = null;
function pick(x, y) {
  const r = 10 * devicePixelRatio;
  let best = null, bestD = r;
  state.via.forEach((v, i) => {
    const s = project(v.position), d = Math.hypot(s[0] - x, s[1] - y);
    if (d < bestD) { best = i; bestD = d; }
  });
  return best;
}
let last = null; // the pointer's last page position while a button is down
canvas.addEventListener("mousedown", e => {
  const x = e.offsetX * devicePixelRatio, y = e.offsetY * devicePixelRatio;
  dragging = pick(x, y);
  if (dragging === null) orbit = [x, y];
  last = [e.clientX, e.clientY];
  canvas.style.cursor = "grabbing";
});
window.addEventListener("mousemove", e => {
  if (last === null) return;
  const dx = (e.clientX - last[0]) * devicePixelRatio, dy = (e.clientY - last[1]) * devicePixelRatio;
  last = [e.clientX, e.clientY];
  if (dragging !== null) {
    const w = unproject(dx, dy), p = state.via[dragging].position;
    for (let d = 0; d < 3; d++) p[d] = Math.round((p[d] + w[d]) * 1e4) / 1e4;
    pointRows();
    drawSoon();
    gesture();
    learn("exact");
  } else if (orbit) {
    view.yaw += dx * 0.005;
    view.pitch = Math.max(-1.5, Math.min(1.5, view.pitch + dy * 0.005));
    drawSoon();
  }
});
window.addEventListener("mouseup", () => {
  last = null;
  if (dragging !== null) {
    dragging = null;
    gesture();
    learn(document.getElementById("solver").value);
  }
  orbit = null;
  canvas.style.cursor = "grab";
  draw();
});
canvas.addEventListener("wheel", e => {
  e.preventDefault();
  view.zoom *= Math.exp(-e.deltaY * 0.001);
  draw();
}, { passive: false });
document.getElementById("tau").addEventListener("change", () => learn(document.getElementById("solver").value));
window.addEventListener("resize", resize);

// Tests and scripts move a via point by numbers: studio.moveVia(0, [x, y, z]).
window.studio = {
  state,
  latencies,
  // Demonstrations by content (tests, scripts): [{name, text}].
  imitateTexts(files) { state.demoFiles = files; return imitate(); },
  moveVia(i, position, solver = "exact") {
    state.via[i].position = position.slice();
    pointRows();
    draw();
    return learn(solver);
  },
  // What the 3-D view shows now (Scene3D.census), null without WebGL.
  census() { draw(); return Scene3D.census(); },
  // One redraw of the view, finished (the 3-D view's pixels read back), in ms.
  redraw() { const t0 = performance.now(); draw(); Scene3D.finish(); return performance.now() - t0; },
  view,
  // Where via point i is on the page, CSS pixels.
  screenOf(i) {
    const r = canvas.getBoundingClientRect(), s = project(state.via[i].position);
    return [r.left + s[0] / devicePixelRatio, r.top + s[1] / devicePixelRatio];
  },
};

// `#move=i,x,y,z[,exact|cmaes]` in the address moves via point i once the first answer
// is in (a link to a configuration; the browser test uses it).
function applyAddress() {
  const m = /^#move=(\d+),([-\d.e]+),([-\d.e]+),([-\d.e]+)(?:,(exact|cmaes))?$/.exec(location.hash);
  if (m && state.via[Number(m[1])]) {
    return window.studio.moveVia(Number(m[1]), [Number(m[2]), Number(m[3]), Number(m[4])], m[5] || "exact");
  }
}

// ---------------------------------------------------------------- files
// An experiment's task (from /api/open or /api/initial) becomes the page's state.
function adopt(task) {
  state.name = task.name;
  state.start = task.start;
  state.goal = task.goal;
  state.tau = task.tau;
  state.via = task.via;
  for (const k of Object.keys(state.weights)) state.weights[k] = task.weights[k];
  document.getElementById("tau").value = String(task.tau);
  pointRows();
  weightRows();
  draw();
}
function download(name, text, type) {
  const a = document.createElement("a");
  a.href = URL.createObjectURL(new Blob([text], { type }));
  a.download = name;
  a.click();
  setTimeout(() => URL.revokeObjectURL(a.href), 1000);
}
function request(solver) {
  return {
    start: state.start, goal: state.goal, tau: Number(document.getElementById("tau").value),
    via: state.via, solver, weights: state.weights,
  };
}
document.getElementById("open").addEventListener("change", async e => {
  const file = e.target.files[0];
  if (!file) return;
  const reply = await fetch("/api/open", {
    method: "POST", headers: { "content-type": "application/json" },
    body: JSON.stringify({ name: file.name, text: await file.text() }),
  });
  const body = await reply.json();
  document.getElementById("file-error").textContent = reply.ok ? "" : body.error;
  if (reply.ok) { adopt(body); learn("exact"); }
});
document.getElementById("save").addEventListener("click", async () => {
  const reply = await fetch("/api/save", {
    method: "POST", headers: { "content-type": "application/json" },
    body: JSON.stringify({ name: state.name, task: request(document.getElementById("solver").value) }),
  });
  if (!reply.ok) { document.getElementById("file-error").textContent = (await reply.json()).error; return; }
  document.getElementById("file-error").textContent = "";
  download(`${state.name}.toml`, await reply.text(), "application/toml");
});
document.getElementById("export").addEventListener("click", async () => {
  const format = document.getElementById("format").value;
  const reply = await fetch("/api/export", {
    method: "POST", headers: { "content-type": "application/json" },
    body: JSON.stringify({ format, task: request(document.getElementById("solver").value) }),
  });
  if (!reply.ok) { document.getElementById("file-error").textContent = (await reply.json()).error; return; }
  document.getElementById("file-error").textContent = "";
  const name = (reply.headers.get("content-disposition") || "").split('"')[1] || "trajectory";
  const a = document.createElement("a");
  a.href = URL.createObjectURL(await reply.blob());
  a.download = `${state.name}_${name}`;
  a.click();
});
document.getElementById("csv").addEventListener("click", () => {
  const p = state.path;
  if (!p) return;
  const axes = p.position[0].length === 3 ? ["x", "y", "z"] : p.position[0].map((_, d) => `y${d}`);
  const rows = [["t", ...axes].join(",")];
  p.t.forEach((t, k) => rows.push([t, ...p.position[k]].join(",")));
  download(`${state.name}_trajectory.csv`, rows.join("\n") + "\n", "text/csv");
});

// ---------------------------------------------------------------- imitation
async function imitate() {
  if (!state.demoFiles.length) return;
  const lambda = document.getElementById("lambda").value;
  const reply = await fetch("/api/imitate", {
    method: "POST", headers: { "content-type": "application/json" },
    body: JSON.stringify({
      demos: state.demoFiles,
      bases: Number(document.getElementById("bases").value),
      method: document.getElementById("method").value,
      lambda: lambda === "" ? null : Number(lambda),
      via: conditioning(),
    }),
  });
  const body = await reply.json();
  document.getElementById("imitation-error").textContent = reply.ok ? "" : body.error;
  if (!reply.ok) return;
  state.imitation = body;
  const rows = body.names.map((n, d) => [`${n}: RMSE`, `${fmt(body.rmse[d] * 1e3, 3)} mm (λ ${body.lambda[d].toExponential(1)})`]);
  if (body.promp) {
    body.names.forEach((n, d) => {
      const mean = body.promp.std.reduce((a, s) => a + s[d], 0) / body.promp.std.length;
      rows.push([`${n}: ProMP mean σ`, `${fmt(mean * 1e3, 1)} mm`]);
    });
  }
  if (body.names.length !== 3) rows.push(["view", "3-D view draws x, y, z demonstrations only"]);
  const tbody = document.querySelector("#imitation tbody");
  tbody.innerHTML = "";
  for (const [k, v] of [[`${body.demos.length} demonstration(s)`, body.names.join(", ")], ...rows]) {
    const tr = document.createElement("tr");
    tr.innerHTML = "<td></td><td></td>";
    tr.children[0].textContent = k;
    tr.children[1].textContent = v;
    tbody.append(tr);
  }
  document.body.dataset.imitated = String(body.demos.length);
  document.body.dataset.conditioned = String(Boolean(body.promp && body.promp.conditioned));
  drawBand(body);
  draw();
}
// The ProMP via point of the inputs, or none.
function conditioning() {
  const t = document.getElementById("cond-t").value, p = document.getElementById("cond-p").value.trim();
  if (t === "" || p === "") return [];
  return [{ time: Number(t), position: p.split(",").map(Number) }];
}
document.getElementById("cond").addEventListener("click", imitate);
// One panel per dimension over time: demonstrations (grey), the ProMP's mean ± 2σ
// (purple band), conditioned (green), the DMP (orange).
function drawBand(im) {
  const c = document.getElementById("band"), g = c.getContext("2d");
  c.style.display = "block";
  g.clearRect(0, 0, c.width, c.height);
  const dims = im.names.length, h = c.height / dims, w = c.width;
  const tEnd = Math.max(im.dmp.t[im.dmp.t.length - 1], im.promp ? im.promp.t[im.promp.t.length - 1] : 0);
  for (let d = 0; d < dims; d++) {
    const all = [...im.demos.flatMap(x => x.values.map(v => v[d])), ...im.dmp.values.map(v => v[d])];
    if (im.promp) im.promp.mean.forEach((m, k) => all.push(m[d] + 2 * im.promp.std[k][d], m[d] - 2 * im.promp.std[k][d]));
    const lo = Math.min(...all), hi = Math.max(...all), span = hi - lo || 1;
    const X = t => 30 + (w - 36) * t / tEnd, Y = v => d * h + h - 6 - (h - 14) * (v - lo) / span;
    const curve = (ts, vs, color, width) => {
      g.strokeStyle = color; g.lineWidth = width; g.beginPath();
      ts.forEach((t, k) => (k ? g.lineTo(X(t), Y(vs[k])) : g.moveTo(X(t), Y(vs[k]))));
      g.stroke();
    };
    const band = (mean, std, color) => {
      g.fillStyle = color; g.beginPath();
      im.promp.t.forEach((t, k) => (k ? g.lineTo(X(t), Y(mean[k][d] + 2 * std[k][d])) : g.moveTo(X(t), Y(mean[k][d] + 2 * std[k][d]))));
      for (let k = im.promp.t.length - 1; k >= 0; k--) g.lineTo(X(im.promp.t[k]), Y(mean[k][d] - 2 * std[k][d]));
      g.fill();
    };
    if (im.promp) band(im.promp.mean, im.promp.std, "rgba(142, 68, 173, 0.18)");
    if (im.promp && im.promp.conditioned) band(im.promp.conditioned[0], im.promp.conditioned[1], "rgba(39, 174, 96, 0.3)");
    for (const demo of im.demos) curve(demo.t, demo.values.map(v => v[d]), "#aaa", 1);
    if (im.promp) curve(im.promp.t, im.promp.mean.map(m => m[d]), "#8e44ad", 1.5);
    if (im.promp && im.promp.conditioned) curve(im.promp.t, im.promp.conditioned[0].map(m => m[d]), "#27ae60", 1.5);
    curve(im.dmp.t, im.dmp.values.map(v => v[d]), "#e67e22", 1.5);
    g.fillStyle = "#222"; g.font = "11px system-ui";
    g.fillText(im.names[d], 2, d * h + 12);
  }
}
async function addDemos(files) {
  state.demoFiles = await Promise.all([...files].map(async f => ({ name: f.name, text: await f.text() })));
  imitate();
}
document.getElementById("demos").addEventListener("change", e => addDemos(e.target.files));
for (const id of ["bases", "method", "lambda"]) document.getElementById(id).addEventListener("change", imitate);
canvas.addEventListener("dragover", e => e.preventDefault());
canvas.addEventListener("drop", e => { e.preventDefault(); addDemos(e.dataTransfer.files); });

// ---------------------------------------------------------------- the robot's animation
const slider = document.getElementById("time");
let playing = null;
function player() {
  const frames = state.path && state.path.robot ? state.path.robot.frames.length : 0;
  slider.max = String(Math.max(0, frames - 1));
  slider.value = state.frame < 0 ? slider.max : String(state.frame);
  strip();
  clock();
}
// The poses where a pair comes within the margin (the guard's collisions).
function collisionFrames(r) {
  if (!(r && r.near && state.robot && state.robot.shapes)) return [];
  const margin = state.robot.shapes.margin, out = [];
  r.near.forEach((n, k) => { if (n.some(p => p.distance < margin)) out.push(k); });
  return out;
}
// Under the slider, each pose's worst pair: red within the margin, orange a near miss.
function strip() {
  const c = document.getElementById("strip"), g = c.getContext("2d");
  g.clearRect(0, 0, c.width, c.height);
  const r = state.path && state.path.robot;
  if (!(r && r.near && r.near.length > 1 && state.robot.shapes)) return;
  const margin = state.robot.shapes.margin, w = c.width / r.near.length;
  r.near.forEach((n, k) => {
    if (!n.length) return;
    const d = Math.min(...n.map(p => p.distance));
    g.fillStyle = d < margin ? "#db1a1f" : "#ff9419";
    g.fillRect(k * w, 0, Math.max(w, 1), c.height);
  });
}
// What the 3-D view shows, for tests and scripts: shades among its drawn pixels and how
// many are the collision's red, after every answer when the address asks (`?census`:
// reading the pixels back costs more than drawing them).
const counting = new URLSearchParams(location.search).has("census");
function census() {
  document.body.dataset.gl = String(Scene3D.active);
  if (!counting) return;
  const c = Scene3D.census();
  document.body.dataset.drawnPixels = c ? String(c.drawn) : "0";
  if (c) {
    document.body.dataset.shades = String(c.shades);
    document.body.dataset.redPixels = String(c.red);
  }
}
function clock() {
  const r = state.path && state.path.robot;
  const k = Number(slider.value);
  document.getElementById("clock").textContent = r && r.t.length ? `${fmt(r.t[Math.min(k, r.t.length - 1)], 2)} s` : "";
}
slider.addEventListener("input", () => { state.frame = Number(slider.value); clock(); drawSoon(); });
document.getElementById("play").addEventListener("click", () => {
  const r = state.path && state.path.robot;
  if (!r || !r.frames.length) return;
  if (playing) { cancelAnimationFrame(playing); playing = null; return; }
  const t0 = performance.now(), end = r.t[r.t.length - 1];
  let shown = 0, started = t0;
  const tick = now => {
    const t = (now - t0) / 1000;
    const k = r.t.findIndex(x => x >= t);
    state.frame = k < 0 ? r.frames.length - 1 : k;
    slider.value = String(state.frame);
    clock();
    draw();
    shown += 1;
    if (now > started) document.body.dataset.fps = String(Math.round(shown / ((now - started) / 1000)));
    if (t < end) playing = requestAnimationFrame(tick);
    else playing = null;
  };
  playing = requestAnimationFrame(tick);
});
document.getElementById("robot").addEventListener("change", () => learn("exact"));

pointRows();
weightRows();
resize();
Promise.all([
  fetch("/api/robot").then(r => (r.ok ? r.json() : null)).catch(() => null),
  fetch("/api/initial").then(r => (r.ok ? r.json() : null)).catch(() => null),
]).then(([view, task]) => {
  state.robot = view;
  if (view && view.shapes && Scene3D.init(glCanvas)) {
    Scene3D.setShapes(view.shapes);
    // A floor grid where nothing stands for one (a table would hide it).
    if (!view.shapes.obstacles.length) Scene3D.setGrid(view.points[0], view.points[0][2]);
  }
  if (task) adopt(task);
  draw();
  return learn("exact");
}).then(applyAddress);
