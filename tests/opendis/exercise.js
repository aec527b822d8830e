// A small DIS exercise built with Open-DIS for JavaScript (npm open-dis
// 1.3.6): entities placed by lon/lat/height, heading and speed, sent as
// Entity State PDUs every interval for a bounded time, plus one Fire and
// one Detonation PDU; tests/opendis/test_opendis_exercise.cpp has a
// `sandtable sim --dis` watch it and checks where it tracks them
// (docs/DIS.md §10).
//
//   node exercise.js send ADDRESS PORT SPEC     sends; prints what it sent
//   node exercise.js where SPEC ELAPSED_S       where each entity is then
//
// SPEC is JSON text (starting with "{") or a file holding it:
//   {"exercise": 1, "site": 7, "application": 9, "seconds": 3, "interval_s": 0.2,
//    "entities": [{"entity": 1, "version": 7, "marking": "ODIS7 TANK", "type": [1,1,225,1,1,1,0],
//                  "force": 1, "lon": 13.3, "lat": 42.3, "height": 300, "heading_deg": 60,
//                  "speed_ms": 8, "climb_ms": 0, "timestamp": "relative" | "absolute"}, ...],
//    "fire": {"at_s": 1.0, "firing": 1, "target": 3, "version": 7},
//    "detonation": {"at_s": 1.4}}
// lon/lat/height (WGS-84 degrees, metres above the ellipsoid) are where an
// entity is at the exercise's start, t0; ELAPSED_S is seconds after t0.
//
// Each entity moves at a constant geocentric velocity: `speed_ms` along
// `heading_deg` (clockwise from true north) in the plane tangent to the
// ellipsoid at its start, plus `climb_ms` up the normal. Its position at t
// is p0 + v (t - t0): exactly what FPW dead reckoning (algorithm 2) from
// any of its PDUs gives, so a receiver that reckons correctly is off only
// by its timing. p0 comes from Open-DIS's own CoordinateConversion
// (getXYZfromLatLonAltDegrees, WGS-84), and `where` converts back with its
// convertDisToLatLongInDegrees: nothing of Sandtable's geodesy. (Open-DIS's
// RangeCoordinates.ENUtoECEF takes degrees into Math.sin, so the tangent
// axes are written out below instead.)
//
// Orientation (IEEE 1278.1 Euler angles psi, theta, phi: rotations about
// the geocentric Z, then the new Y, then the new X, taking the geocentric
// axes to the body axes x forward, y right, z down). With the local axes at
// latitude B and longitude L
//   N = (-sin B cos L, -sin B sin L, cos B), E = (-sin L, cos L, 0),
//   D = (-cos B cos L, -cos B sin L, -sin B),
// heading h, pitch p = atan2(climb, speed) and no roll, the body axes are
//   x = cos p (cos h N + sin h E) - sin p D,  y = -sin h N + cos h E,  z = x × y,
// and since x = (cos theta cos psi, cos theta sin psi, -sin theta),
// y_Z = cos theta sin phi and z_Z = cos theta cos phi:
//   psi = atan2(x_Y, x_X),  theta = asin(-x_Z),  phi = atan2(y_Z, z_Z).
// For p = 0 that is theta = -asin(cos h cos B), phi = atan2(-sin h cos B, -sin B).
//
// One Open-DIS build per process (opendis.js): `send` starts one child
// process per DIS version in the spec, each sending its own entities on
// the same schedule from the same t0; the Fire and Detonation go out from
// the child of `fire.version`. Every loop is bounded by the spec's
// `seconds` (at most 30) and entity count (at most 100).
'use strict';

const dgram = require('dgram');
const fs = require('fs');
const {spawn} = require('child_process');
const {performance} = require('perf_hooks');
const od = require('./opendis.js');

const DEG = Math.PI / 180;
const f = Math.fround;
const nowUnixS = () => (performance.timeOrigin + performance.now()) / 1000;

function fail(message) {
  process.stderr.write('exercise.js: ' + message + '\n');
  process.exit(2);
}

// ------------------------------------------------------------- the spec

function readSpec(text) {
  if (!text) fail('no SPEC');
  let spec;
  try {
    spec = JSON.parse(text.trimStart().startsWith('{') ? text : fs.readFileSync(text, 'utf8'));
  } catch (e) {
    fail('SPEC: ' + e.message);
  }
  const s = Object.assign({exercise: 1, site: 7, application: 9, seconds: 3, interval_s: 0.2}, spec);
  if (!(s.seconds > 0 && s.seconds <= 30)) fail('SPEC seconds must be in (0, 30]');
  if (!(s.interval_s >= 0.01 && s.interval_s <= s.seconds)) fail('SPEC interval_s must be in [0.01, seconds]');
  if (!Array.isArray(s.entities) || s.entities.length < 1 || s.entities.length > 100) {
    fail('SPEC entities must be 1 to 100 entities');
  }
  s.entities = s.entities.map((e, k) => {
    const x = Object.assign({entity: k + 1, version: 7, marking: 'ODIS ' + (k + 1), type: [1, 1, 225, 1, 1, 1, 0],
                             force: 1, height: 0, heading_deg: 0, speed_ms: 0, climb_ms: 0, timestamp: 'relative'}, e);
    if (!Number.isFinite(x.lon) || !Number.isFinite(x.lat)) fail('SPEC entity ' + x.entity + ' needs lon and lat');
    od.versionArg(String(x.version));
    return x;
  });
  if (s.fire) {
    const known = new Set(s.entities.map((e) => e.entity));
    if (!known.has(s.fire.firing) || !known.has(s.fire.target)) fail('SPEC fire.firing and fire.target must be entities');
  }
  return s;
}

// ------------------------------------------------------- the kinematics

/** The local north, east and down unit vectors (geocentric) at lat, lon. */
function localAxes(latDeg, lonDeg) {
  const sb = Math.sin(latDeg * DEG), cb = Math.cos(latDeg * DEG);
  const sl = Math.sin(lonDeg * DEG), cl = Math.cos(lonDeg * DEG);
  return {n: [-sb * cl, -sb * sl, cb], e: [-sl, cl, 0], d: [-cb * cl, -cb * sl, -sb]};
}

const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const scale = (a, k) => [a[0] * k, a[1] * k, a[2] * k];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];

/** An entity's motion: its geocentric start, velocity (the float32s the
 * PDU carries, so reckoning from the wire is exact) and Euler angles. */
function motionOf(e, dis) {
  const c = new dis.CoordinateConversion().getXYZfromLatLonAltDegrees({lat: e.lat, lon: e.lon, alt: e.height});
  const ax = localAxes(e.lat, e.lon);
  const h = e.heading_deg * DEG;
  const level = add(scale(ax.n, Math.cos(h)), scale(ax.e, Math.sin(h)));
  const v = add(scale(level, e.speed_ms), scale(ax.d, -e.climb_ms)).map(f);
  const p = Math.atan2(e.climb_ms, e.speed_ms);
  const x = add(scale(level, Math.cos(p)), scale(ax.d, -Math.sin(p)));
  const y = add(scale(ax.n, -Math.sin(h)), scale(ax.e, Math.cos(h)));
  const z = cross(x, y);
  const euler = [Math.atan2(x[1], x[0]), Math.asin(-x[2]), Math.atan2(y[2], z[2])].map(f);
  return {p0: [c.x, c.y, c.z], v, euler};
}

const positionAt = (m, elapsedS) => add(m.p0, scale(m.v, elapsedS));

const idText = (s, e) => s.site + ':' + s.application + ':' + e.entity;

/** DIS timestamp (IEEE 1278.1 6.2.88): 2^31 units an hour, bit 0 set when
 * absolute (seconds past the UTC hour), clear when relative (here: past
 * the hour of the sender's own clock started at t0). */
function timestamp(unixS, t0, absolute) {
  const past = absolute ? unixS % 3600 : (unixS - t0) % 3600;
  const units = Math.min(Math.floor((past / 3600) * 2 ** 31), 2 ** 31 - 1);
  return units * 2 + (absolute ? 1 : 0);
}

// ------------------------------------------------------------ one child

/** Sends the entities of one DIS version (and the Fire and Detonation
 * when `fire.version` is it) on the spec's schedule from t0; prints what
 * it sent. */
function runVersion(version, address, port, spec, t0) {
  const dis = od.load(version);
  const {setId, setEventId, setType, setVec, setDescriptor} = od.fields(version);
  const mine = spec.entities.filter((e) => e.version === version);
  const motions = new Map(spec.entities.map((e) => [e.entity, motionOf(e, dis)]));
  const report = {version, entity_states: 0, fires: 0, detonations: 0, first_send_unix_s: null, last_send_unix_s: null};
  const socket = dgram.createSocket('udp4');
  let pending = 0, scheduled = 0, closing = false;

  function header(pdu, length, unixS, absolute) {
    pdu.exerciseID = spec.exercise;
    pdu.timestamp = timestamp(unixS, t0, absolute);
    if (version === 7) pdu.length = length;
    else pdu.pduLength = length;
  }
  function send(pdu, kind) {
    const out = new dis.OutputStream(new ArrayBuffer(1024));
    pdu.encodeToBinary(out);
    const t = nowUnixS();
    report.first_send_unix_s = report.first_send_unix_s ?? t;
    report.last_send_unix_s = t;
    ++report[kind];
    ++pending;
    socket.send(Buffer.from(out.toByteArray()), port, address, (error) => {
      if (error) fail('send to ' + address + ':' + port + ': ' + error.message);
      --pending;
      finishIfDone();
    });
  }
  function finishIfDone() {
    if (closing || pending > 0 || scheduled > 0) return;
    closing = true;
    socket.close();
    process.stdout.write(JSON.stringify(report) + '\n');
  }
  function at(offsetS, action) {
    ++scheduled;
    setTimeout(() => {
      action();
      --scheduled;
      finishIfDone();
    }, Math.max(0, (t0 + offsetS - nowUnixS()) * 1000));
  }

  function entityState(e) {
    const m = motions.get(e.entity);
    const t = nowUnixS();
    const pdu = new dis.EntityStatePdu();
    header(pdu, 144, t, e.timestamp === 'absolute');
    setId(pdu.entityID, [spec.site, spec.application, e.entity]);
    pdu.forceId = e.force;
    setType(pdu.entityType, e.type);
    setVec(pdu.entityLinearVelocity, m.v);
    setVec(pdu.entityLocation, positionAt(m, t - t0));
    pdu.entityOrientation.psi = m.euler[0];
    pdu.entityOrientation.theta = m.euler[1];
    pdu.entityOrientation.phi = m.euler[2];
    pdu.deadReckoningParameters.deadReckoningAlgorithm = 2;  // FPW
    pdu.marking.characterSet = 1;
    pdu.marking.setMarking(e.marking);
    if (version === 7) pdu.numberOfVariableParameters = 0;
    else pdu.numberOfArticulationParameters = 0;
    send(pdu, 'entity_states');
  }

  const munition = {munition: [2, 2, 225, 2, 2, 1, 0], warhead: 1000, fuse: 1000, quantity: 1, rate: 0};
  const firing = spec.fire ? [spec.site, spec.application, spec.fire.firing] : null;
  const target = spec.fire ? [spec.site, spec.application, spec.fire.target] : null;
  const round = [spec.site, spec.application, 500];
  const event = [spec.site, spec.application, 1];
  function warfareIds(pdu) {
    setId(pdu.firingEntityID, firing);
    setId(pdu.targetEntityID, target);
    setId(version === 7 ? pdu.munitionExpendibleID || pdu.explodingEntityID : pdu.munitionID, round);
    setEventId(pdu.eventID, event);
  }
  function fire() {
    const t = nowUnixS();
    const from = positionAt(motions.get(spec.fire.firing), t - t0);
    const to = positionAt(motions.get(spec.fire.target), t - t0);
    const d = add(to, scale(from, -1));
    const range = Math.hypot(...d);
    const pdu = new dis.FirePdu();
    header(pdu, 96, t, false);
    warfareIds(pdu);
    setVec(pdu.locationInWorldCoordinates, from);
    setDescriptor(version === 7 ? pdu.descriptor : pdu.burstDescriptor, munition);
    setVec(pdu.velocity, scale(d, 300 / range).map(f));  // 300 m/s at the target
    if (version === 7) pdu.range = f(range);
    else pdu.rangeToTarget = f(range);
    send(pdu, 'fires');
  }
  function detonation() {
    const t = nowUnixS();
    const pdu = new dis.DetonationPdu();
    header(pdu, 104, t, false);
    warfareIds(pdu);
    setVec(pdu.locationInWorldCoordinates, positionAt(motions.get(spec.fire.target), t - t0));
    setDescriptor(version === 7 ? pdu.descriptor : pdu.burstDescriptor, munition);
    pdu.detonationResult = 1;  // entity impact
    if (version === 7) pdu.numberOfVariableParameters = 0;
    else pdu.numberOfArticulationParameters = 0;
    send(pdu, 'detonations');
  }

  socket.bind(0, () => {
    socket.setBroadcast(true);  // 127.255.255.255 and other broadcast addresses need SO_BROADCAST
    const sends = Math.round(spec.seconds / spec.interval_s) + 1;
    for (let k = 0; k < sends; ++k) at(k * spec.interval_s, () => mine.forEach(entityState));
    if (spec.fire && (spec.fire.version ?? 7) === version) {
      at(spec.fire.at_s ?? 1, fire);
      if (spec.detonation) at(spec.detonation.at_s ?? 1.4, detonation);
    }
    finishIfDone();
  });
}

// ------------------------------------------------------------- the modes

function send(address, port, spec) {
  // The children load and bind before t0: 0.3 s is several node starts.
  const t0 = nowUnixS() + 0.3;
  const versions = [...new Set(spec.entities.map((e) => e.version).concat(spec.fire ? [spec.fire.version ?? 7] : []))];
  const dis = od.load(7);  // for the coordinate conversion only
  const entities = spec.entities.map((e) => {
    const m = motionOf(e, dis);
    return {id: idText(spec, e), marking: e.marking, version: e.version, domain: e.type[1], lon: e.lon, lat: e.lat,
            height: e.height, speed_ms: Math.hypot(...m.v), ecef0: m.p0, velocity: m.v, euler: m.euler,
            timestamp: e.timestamp};
  });
  const reports = [];
  let running = versions.length;
  for (const version of versions) {
    const child = spawn(process.execPath, [__filename, 'version', String(version), address, String(port),
                                           JSON.stringify(spec), String(t0)], {stdio: ['ignore', 'pipe', 'inherit']});
    let out = '';
    child.stdout.on('data', (d) => { out += d; });
    child.on('close', (code) => {
      if (code !== 0) fail('the DIS ' + version + ' sender exited ' + code);
      reports.push(JSON.parse(out));
      if (--running > 0) return;
      const sum = (k) => reports.reduce((a, r) => a + r[k], 0);
      process.stdout.write(JSON.stringify({
        t0_unix_s: t0, exercise: spec.exercise, address, port, entities, senders: reports,
        entity_states: sum('entity_states'), fires: sum('fires'), detonations: sum('detonations'),
        first_send_unix_s: Math.min(...reports.map((r) => r.first_send_unix_s)),
        last_send_unix_s: Math.max(...reports.map((r) => r.last_send_unix_s)),
      }, null, 1) + '\n');
    });
  }
}

function where(spec, elapsedS) {
  const dis = od.load(7);
  const convert = new dis.CoordinateConversion();
  const entities = spec.entities.map((e) => {
    const p = positionAt(motionOf(e, dis), elapsedS);
    const g = convert.convertDisToLatLongInDegrees({x: p[0], y: p[1], z: p[2]});
    return {id: idText(spec, e), marking: e.marking, domain: e.type[1], lon: g.longitude, lat: g.latitude,
            height: g.altitude, ecef: p};
  });
  process.stdout.write(JSON.stringify({elapsed_s: elapsedS, entities}, null, 1) + '\n');
}

function portArg(text) {
  const port = Number(text);
  if (!(Number.isInteger(port) && port > 0 && port < 65536)) fail('PORT "' + text + '" is not 1 to 65535');
  return port;
}

const [mode, ...args] = process.argv.slice(2);
if (mode === 'send' && args.length === 3) {
  send(args[0], portArg(args[1]), readSpec(args[2]));
} else if (mode === 'where' && args.length === 2 && Number.isFinite(Number(args[1]))) {
  where(readSpec(args[0]), Number(args[1]));
} else if (mode === 'version' && args.length === 5) {
  runVersion(od.versionArg(args[0]), args[1], portArg(args[2]), readSpec(args[3]), Number(args[4]));
} else {
  fail('usage: node exercise.js send ADDRESS PORT SPEC | where SPEC ELAPSED_S');
}
