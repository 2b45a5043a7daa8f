// strol-bench serve's page: shows the server's frames and panel, sends the keys held and the
// gamepad's state. It sends nothing else: no path, no code; the server checks every message.
"use strict";

const token = new URLSearchParams(location.search).get("token") || "";
const $ = (id) => document.getElementById(id);
let known = new Set();
let ws = null;
let running = false;
let seq = 0;
const held = new Set();
let pad = null;
const sentAt = new Map();
const stats = { frames: 0, fps: 0, latencyMs: [], corrections: 0, ended: [], panels: 0 };
window.strolStats = stats;  // read by the tests and the load benchmark
let frameUrl = null;
let fpsCount = 0;
let fpsSince = performance.now();

function show(id) {
  for (const s of document.querySelectorAll("section")) s.hidden = s.id !== id;
}

function fill(list, lines, cls) {
  list.replaceChildren(...lines.map((t) => {
    const li = document.createElement("li");
    li.textContent = t;
    if (cls) li.className = cls(t);
    return li;
  }));
}

function fail(text) {
  $("error-what").textContent = text;
  show("error");
}

async function intro() {
  const r = await fetch("/api/intro?token=" + encodeURIComponent(token));
  if (!r.ok) { fail("This link is not valid (ask the researcher for the full link)."); return; }
  const info = await r.json();
  known = new Set(info.known_keys);
  $("study").textContent = info.study;
  $("consent").textContent = info.consent;
  fill($("plan"), info.sessions);
  show("intro");
}

function send(obj) {
  if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(obj));
}

let sessionFrames = 0;  // frames of the running session: latency counts once it shows

function sendInput() {
  if (!running) return;
  seq += 1;
  if (sessionFrames > 0) sentAt.set(seq, performance.now());
  if (sentAt.size > 200) sentAt.delete(sentAt.keys().next().value);
  send({ t: "input", n: seq, keys: [...held], pad: pad });
}

function onFrame(buf) {
  const ack = new DataView(buf).getUint32(0);
  if (sentAt.has(ack)) {  // the first frame drawn after that input reached the env
    stats.latencyMs.push(performance.now() - sentAt.get(ack));
    if (stats.latencyMs.length > 500) stats.latencyMs.shift();
    sentAt.delete(ack);
  }
  const url = URL.createObjectURL(new Blob([buf.slice(4)], { type: "image/jpeg" }));
  $("frame").src = url;
  if (frameUrl) URL.revokeObjectURL(frameUrl);
  frameUrl = url;
  stats.frames += 1;
  sessionFrames += 1;
  fpsCount += 1;
  const now = performance.now();
  if (now - fpsSince > 1000) {
    stats.fps = fpsCount * 1000 / (now - fpsSince);
    fpsCount = 0;
    fpsSince = now;
    const lat = stats.latencyMs.slice(-20);
    const med = lat.length ? [...lat].sort((a, b) => a - b)[lat.length >> 1] : NaN;
    const shown = Number.isNaN(med) ? "" : `, key to picture ${med.toFixed(0)} ms`;
    $("stats").textContent = `${stats.fps.toFixed(1)} frames/s${shown}`;
  }
}

function onPanel(p) {
  stats.panels += 1;
  $("teach").textContent = p.teach || "";
  fill($("state"), p.state || []);
  fill($("cues"), p.cues || [], (t) => (t.startsWith("TOO HARD") || t.startsWith("BRAKED")
    ? "hard" : t.startsWith("CORRECTION") || t.startsWith("PUSH COUNTS") ? "ok" : ""));
  const m = /corrections:? (\d+)/.exec((p.state || []).join("\n"));
  if (m) stats.corrections = Number(m[1]);
  if (typeof p.push === "number") {
    $("push").textContent = p.push.toFixed(0);
    $("harder").textContent = p.harder ? "(harder: the arm will brake)" : "";
    const fillBar = $("bar-fill");
    fillBar.style.width = Math.min(100, p.push) + "%";
    fillBar.className = p.harder ? "hard" : "";
  }
}

function onText(m) {
  if (m.t === "hello") {
    $("who").textContent = "participant " + m.participant;
  } else if (m.t === "next") {
    running = false;
    $("next-label").textContent = m.label;
    $("next-what").textContent = (m.practice ? "A short practice. " : "") +
      (m.kind === "arm" ? "Push the robot arm's cup to teach it." :
        "Correct the blue car (yours) to teach the green robot car.") +
      ` It lasts ${m.duration} s.`;
    fill($("next-keys"), m.keys);
    fill($("keys-help"), m.keys);
    $("run-label").textContent = m.label;
    show("next");
    $("start").focus();
  } else if (m.t === "panel") {
    onPanel(m);
  } else if (m.t === "ended") {
    running = false;
    stats.ended.push(m);
    const what = `${m.reason}, ${m.corrections} correction(s)`;
    $("ended-what").textContent = `It ended (${what}).`;
    $("last").textContent = `Last session: ${what}.`;
    show("ended");
  } else if (m.t === "done") {
    $("done-id").textContent = m.participant;
    show("done");
  } else if (m.t === "full") {
    fail("The study is full right now: please try again in a few minutes.");
  }
}

function connect() {
  const scheme = location.protocol === "https:" ? "wss://" : "ws://";
  ws = new WebSocket(scheme + location.host + "/ws?token=" + encodeURIComponent(token));
  ws.binaryType = "arraybuffer";
  ws.onmessage = (e) => (typeof e.data === "string" ? onText(JSON.parse(e.data)) : onFrame(e.data));
  ws.onclose = () => { running = false; };
}

function start() {
  held.clear();
  sentAt.clear();
  sessionFrames = 0;
  send({ t: "start" });
  running = true;
  show("run");
  $("frame").tabIndex = 0;
  $("frame").focus();
}

function keyName(e) { return e.key.toLowerCase(); }

window.addEventListener("keydown", (e) => {
  const k = keyName(e);
  if (!running || !known.has(k)) return;
  e.preventDefault();
  if (!held.has(k)) { held.add(k); sendInput(); }
});
window.addEventListener("keyup", (e) => {
  const k = keyName(e);
  if (held.delete(k)) { e.preventDefault(); sendInput(); }
});
window.addEventListener("blur", () => { if (held.size) { held.clear(); sendInput(); } });

// The gamepad (W3C standard mapping), read 20 times a second, sent when it changes.
let lastPad = "";
setInterval(() => {
  if (!running || !navigator.getGamepads) return;
  const g = [...navigator.getGamepads()].find((x) => x && x.mapping === "standard");
  pad = g ? { axes: g.axes.slice(0, 8).map((a) => Math.max(-1, Math.min(1, a))),
    buttons: g.buttons.slice(0, 20).map((b) => b.value) } : null;
  const now = JSON.stringify(pad);
  if (now !== lastPad) { lastPad = now; sendInput(); }
}, 50);

$("agree").addEventListener("click", () => { connect(); $("agree").disabled = true; });
$("start").addEventListener("click", start);
intro().catch((e) => fail("Cannot reach the server: " + e));
