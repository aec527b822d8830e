// Builds an Entity State, a Fire and a Detonation PDU with Open-DIS for
// JavaScript (npm open-dis 1.3.6) in DIS version 6 or 7, writes each PDU's
// bytes to a file, and prints a JSON of every field value it set, which
// tests/opendis/test_opendis.cpp checks against sandtable::dis::decode.
//
//   node write_pdus.js VERSION OUTDIR
//
// Writes OUTDIR/opendisV_es.bin, opendisV_fire.bin, opendisV_detonation.bin
// and prints {"version": V, "pdus": [{"file", "header", "entityState" |
// "fire" | "detonation"}]} on stdout. Floats are set through Math.fround,
// so the JSON holds the float32 values exactly.
//
// Open-DIS leaves the PDU length and the record counts to the caller; they
// are set here from the standard's sizes. The records are built the way the
// standard lays them out, through what each build offers (docs/DIS.md §10):
// - version 7: ArticulatedParts and AttachedParts, whose 64-bit value is a
//   decimal string of a signed integer (the float32 in its high half, or
//   the attached entity type's 8 bytes);
// - version 6: ArticulationParameter, whose value is a float64 on the wire
//   where the standard has a float32 and 32 bits of padding; the float64
//   with the standard's 8 bytes is set. One more record is set the way
//   Open-DIS 6 means it (a float64 0.5) to pin what a receiver that follows
//   the standard reads from such a sender.
'use strict';

const fs = require('fs');
const path = require('path');
const od = require('./opendis.js');

const version = od.versionArg(process.argv[2]);
const outDir = process.argv[3];
if (!outDir) throw new Error('usage: node write_pdus.js VERSION OUTDIR');
const dis = od.load(version);
const f = Math.fround;

// ------------------------------------------------------------ the values

const header = {exercise: 9, timestamp: 0x9e3779b9, status: version === 7 ? 0x06 : 0};

const entityState = {
  id: [42, 17, 1001],
  force: 2,
  type: [1, 1, 222, 2, 2, 1, 4],
  alternativeType: [1, 1, 225, 1, 1, 0, 0],
  velocity: [f(12.345), f(-0.003125), f(0.1)],
  location: [-2707134.123456789, -4353427.987654321, 3781216.0625],
  orientation: [f(-2.0943951), f(0.0872665), f(-0.0174533)],
  appearance: 0x80410018,  // bit 31 set: Open-DIS 6 writes and reads it as a signed int
  deadReckoning: {
    algorithm: version === 7 ? 8 : 4,
    other: [1, 0x80, 0xff, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 0xfe, 14],
    acceleration: [f(0.5), f(-9.80665), f(0.001)],
    angularVelocity: [f(0.01), f(-0.2), f(3.14159)],
  },
  marking: {characterSet: 1, text: version === 7 ? 'OPENDIS-ES7' : 'ODIS6 T72'},
  capabilities: 0xa0000005,
  parameters: [
    {recordType: 0, change: 3, attachedTo: 0, parameterType: 4096 + 11, value: f(-1.2345)},  // turret azimuth
    {recordType: 0, change: 5, attachedTo: 1, parameterType: 4416 + 13, value: f(0.1745329)}, // gun elevation
    {recordType: 1, detached: 0, attachedTo: 0, station: 1, type: [2, 9, 225, 2, 14, 1, 0]},  // a store
  ],
};
if (version === 6) {
  // Turret azimuth rate, set as Open-DIS 6 means its parameterValue.
  entityState.parameters.push(
      {recordType: 0, change: 7, attachedTo: 0, parameterType: 4096 + 12, value: 0.5, writtenAs: 'opendis6-float64'});
}

const munition = [2, 2, 225, 2, 2, 1, 0];
const fire = {
  firing: [42, 17, 1001],
  target: [43, 18, 2002],
  munition: [42, 17, 1500],
  event: [42, 17, 77],
  fireMissionIndex: 0x80000003,  // bit 31 set: Open-DIS 6 writes and reads it as a signed int
  location: [-2707100.5, -4353400.25, 3781200.75],
  descriptor: {munition, warhead: 1000, fuse: 1000, quantity: 2, rate: 600},
  velocity: [f(-250.5), f(100.25), f(50.125)],
  range: f(1234.5),
};

const detonation = {
  firing: [42, 17, 1001],
  target: [43, 18, 2002],
  munition: [42, 17, 1500],
  event: [42, 17, 77],
  velocity: [f(-240.25), f(98.5), f(-20.0625)],
  location: [-2706150.0625, -4352990.5, 3781000.125],
  descriptor: {munition, warhead: 1000, fuse: 1000, quantity: 1, rate: 0},
  entityLocation: [f(1.5), f(-0.75), f(0.3)],
  result: 1,
  parameters: [{recordType: 0, change: 1, attachedTo: 0, parameterType: 4096 + 11, value: f(0.5)}],
};

// ------------------------------------------------------- Open-DIS objects

const {setId, setEventId, setType, setVec, setDescriptor} = od.fields(version);

function setHeader(pdu, length) {
  pdu.exerciseID = header.exercise;
  pdu.timestamp = header.timestamp;
  if (version === 7) {
    pdu.length = length;
    pdu.pduStatus = header.status;
  } else {
    pdu.pduLength = length;
  }
}

/** One variable parameter (articulation parameter) record object. */
function record(p) {
  const field = p.recordType === 0 ? od.float32Field(p.value) : od.entityTypeField(p.type);
  const flag = p.recordType === 0 ? p.change : p.detached;
  const type = p.recordType === 0 ? p.parameterType : p.station;
  if (version === 7) {
    const r = p.recordType === 0 ? new dis.ArticulatedParts() : new dis.AttachedParts();
    r.recordType = p.recordType;
    if (p.recordType === 0) r.changeIndicator = flag;
    else r.detachedIndicator = flag;
    r.partAttachedTo = p.attachedTo;
    r.parameterType = type;
    r.parameterValue = od.asLongString(field);
    return r;
  }
  const r = new dis.ArticulationParameter();
  r.parameterTypeDesignator = p.recordType;
  r.changeIndicator = flag;
  r.partAttachedTo = p.attachedTo;
  r.parameterType = type;
  r.parameterValue = p.writtenAs === 'opendis6-float64' ? p.value : od.asFloat64(field);
  return r;
}

function setRecords(pdu, parameters) {
  const records = parameters.map(record);
  if (version === 7) {
    pdu.numberOfVariableParameters = records.length;
    pdu.variableParameters = records;
  } else {
    pdu.numberOfArticulationParameters = records.length;
    pdu.articulationParameters = records;
  }
}

function buildEntityState() {
  const e = entityState;
  const pdu = new dis.EntityStatePdu();
  setHeader(pdu, 144 + 16 * e.parameters.length);
  setId(pdu.entityID, e.id);
  pdu.forceId = e.force;
  setType(pdu.entityType, e.type);
  setType(pdu.alternativeEntityType, e.alternativeType);
  setVec(pdu.entityLinearVelocity, e.velocity);
  setVec(pdu.entityLocation, e.location);
  pdu.entityOrientation.psi = e.orientation[0];
  pdu.entityOrientation.theta = e.orientation[1];
  pdu.entityOrientation.phi = e.orientation[2];
  pdu.entityAppearance = e.appearance;
  const dr = pdu.deadReckoningParameters;
  dr.deadReckoningAlgorithm = e.deadReckoning.algorithm;
  const other = version === 7 ? dr.parameters : dr.otherParameters;
  e.deadReckoning.other.forEach((b, k) => { other[k] = b; });
  setVec(dr.entityLinearAcceleration, e.deadReckoning.acceleration);
  setVec(dr.entityAngularVelocity, e.deadReckoning.angularVelocity);
  pdu.marking.characterSet = e.marking.characterSet;
  pdu.marking.setMarking(e.marking.text);
  pdu.capabilities = e.capabilities;
  setRecords(pdu, e.parameters);
  return pdu;
}

function setWarfareIds(pdu, w) {
  setId(pdu.firingEntityID, w.firing);
  setId(pdu.targetEntityID, w.target);
  setId(version === 7 ? (pdu.munitionExpendibleID || pdu.explodingEntityID) : pdu.munitionID, w.munition);
  setEventId(pdu.eventID, w.event);
}

function buildFire() {
  const pdu = new dis.FirePdu();
  setHeader(pdu, 96);
  setWarfareIds(pdu, fire);
  pdu.fireMissionIndex = fire.fireMissionIndex;
  setVec(pdu.locationInWorldCoordinates, fire.location);
  setDescriptor(version === 7 ? pdu.descriptor : pdu.burstDescriptor, fire.descriptor);
  setVec(pdu.velocity, fire.velocity);
  if (version === 7) pdu.range = fire.range;
  else pdu.rangeToTarget = fire.range;
  return pdu;
}

function buildDetonation() {
  const d = detonation;
  const pdu = new dis.DetonationPdu();
  setHeader(pdu, 104 + 16 * d.parameters.length);
  setWarfareIds(pdu, d);
  setVec(pdu.velocity, d.velocity);
  setVec(pdu.locationInWorldCoordinates, d.location);
  setDescriptor(version === 7 ? pdu.descriptor : pdu.burstDescriptor, d.descriptor);
  setVec(version === 7 ? pdu.locationOfEntityCoordinates : pdu.locationInEntityCoordinates, d.entityLocation);
  pdu.detonationResult = d.result;
  setRecords(pdu, d.parameters);
  return pdu;
}

// -------------------------------------------------------------- output

function encode(pdu) {
  const out = new dis.OutputStream(new ArrayBuffer(8192));
  pdu.encodeToBinary(out);
  return Buffer.from(out.toByteArray());
}

/** The marking as the 11 bytes the standard puts on the wire. */
function markingChars(text) {
  const chars = [];
  for (let k = 0; k < 11; ++k) chars.push(k < text.length ? text.charCodeAt(k) : 0);
  return chars;
}

const pdus = [];
function emit(name, kind, pdu, body, type, family) {
  const bytes = encode(pdu);
  const file = path.join(outDir, 'opendis' + version + '_' + name + '.bin');
  fs.writeFileSync(file, bytes);
  pdus.push({
    file,
    header: Object.assign({version, type, family, length: bytes.length}, header),
    [kind]: body,
  });
}

const esJson = Object.assign({}, entityState,
    {marking: {characterSet: entityState.marking.characterSet, chars: markingChars(entityState.marking.text)}});
emit('es', 'entityState', buildEntityState(), esJson, 1, 1);
emit('fire', 'fire', buildFire(), fire, 2, 2);
emit('detonation', 'detonation', buildDetonation(), detonation, 3, 2);
process.stdout.write(JSON.stringify({version, pdus}, null, 1) + '\n');
