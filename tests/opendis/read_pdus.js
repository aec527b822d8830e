// Decodes PDU files with Open-DIS for JavaScript (npm open-dis 1.3.6), DIS
// version 6 or 7, and prints every field as JSON, in the layout
// write_pdus.js prints; tests/opendis/test_opendis.cpp compares it with
// what sandtable::dis::encode wrote.
//
//   node read_pdus.js VERSION FILE...
//
// Prints {"version": V, "pdus": [{"file", "header", "entityState" | "fire"
// | "detonation", "raw"}]}. The main part is Open-DIS's fields, moved into
// that layout with two conversions, both spelled out below (docs/DIS.md §10):
// - Open-DIS 6 reads the appearance, the capabilities, the fire mission
//   index and a record's parameter type as signed 32-bit integers, the
//   Entity State record count and the dead reckoning parameters as signed
//   bytes, and both builds read the marking as signed bytes: they are taken
//   modulo 2^32 and 2^8 here;
// - neither build reads the standard's variable parameter records: version
//   6 reads the value field as one float64, version 7 reads a record as a
//   generic layout (a float64 over bytes 1-8, a u32, a u16, a u8). The
//   standard's fields are read back from the bytes of what Open-DIS decoded
//   (version 6: the float64's bytes; version 7: the generic record encoded
//   again and read with Open-DIS's own ArticulatedParts or AttachedParts).
// "raw" keeps Open-DIS's own values of those fields, unconverted.
'use strict';

const fs = require('fs');
const od = require('./opendis.js');

const version = od.versionArg(process.argv[2]);
const files = process.argv.slice(3);
const dis = od.load(version);
const factory = new dis.PduFactory();

const u8 = (v) => v & 0xff;
const u32 = (v) => v >>> 0;
const id = (e) => (version === 7 ? [e.siteID, e.applicationID, e.entityID] : [e.site, e.application, e.entity]);
const eventId = (e) =>
  (version === 7 ? [e.simulationAddress.site, e.simulationAddress.application, e.eventNumber]
                 : [e.site, e.application, e.eventNumber]);
const type = (t) =>
  [t.entityKind, t.domain, t.country, t.category, t.subcategory, version === 7 ? t.specific : t.spec, t.extra];
const vec = (v) => [v.x, v.y, v.z];
const descriptor = (d) => ({
  munition: type(version === 7 ? d.munitionType : d.munition),
  warhead: d.warhead,
  fuse: d.fuse,
  quantity: d.quantity,
  rate: d.rate,
});

/** The standard's fields of one record, and Open-DIS's own values. */
function record(r) {
  let recordType, flag, attachedTo, parameterType, field, raw;
  if (version === 7) {
    // Encode the generic record again and read it as the standard's part record.
    const out = new dis.OutputStream(new ArrayBuffer(16));
    r.encodeToBinary(out);
    const part = r.recordType === 1 ? new dis.AttachedParts() : new dis.ArticulatedParts();
    part.initFromBinary(new dis.InputStream(out.toByteArray()));
    recordType = part.recordType;
    flag = r.recordType === 1 ? part.detachedIndicator : part.changeIndicator;
    attachedTo = part.partAttachedTo;
    parameterType = part.parameterType;
    field = od.fromLongString(part.parameterValue);
    raw = {
      variableParameterFields1: r.variableParameterFields1,
      variableParameterFields2: r.variableParameterFields2,
      variableParameterFields3: r.variableParameterFields3,
      variableParameterFields4: r.variableParameterFields4,
      parameterValue: part.parameterValue,
    };
  } else {
    recordType = r.parameterTypeDesignator;
    flag = r.changeIndicator;
    attachedTo = r.partAttachedTo;
    parameterType = u32(r.parameterType);
    field = od.fromFloat64(r.parameterValue);
    raw = {parameterType: r.parameterType, parameterValue: r.parameterValue};
  }
  if (recordType === 0) {
    const {value, padding} = od.float32OfField(field);
    return {record: {recordType, change: flag, attachedTo, parameterType, value, padding}, raw};
  }
  if (recordType === 1) {
    return {
      record: {recordType, detached: flag, attachedTo, station: parameterType, type: od.entityTypeOfField(field)},
      raw,
    };
  }
  return {record: {recordType, bytes: field}, raw};
}

function header(p) {
  return {
    version: p.protocolVersion,
    exercise: p.exerciseID,
    type: p.pduType,
    family: p.protocolFamily,
    timestamp: p.timestamp,
    length: version === 7 ? p.length : p.pduLength,
    status: version === 7 ? p.pduStatus : 0,
  };
}

function entityState(p, raw) {
  const records = (version === 7 ? p.variableParameters : p.articulationParameters).map(record);
  const dr = p.deadReckoningParameters;
  raw.appearance = p.entityAppearance;
  raw.capabilities = p.capabilities;
  raw.recordCount = version === 7 ? p.numberOfVariableParameters : p.numberOfArticulationParameters;
  raw.records = records.map((r) => r.raw);
  return {
    id: id(p.entityID),
    force: p.forceId,
    type: type(p.entityType),
    alternativeType: type(p.alternativeEntityType),
    velocity: vec(p.entityLinearVelocity),
    location: vec(p.entityLocation),
    orientation: [p.entityOrientation.psi, p.entityOrientation.theta, p.entityOrientation.phi],
    appearance: u32(p.entityAppearance),
    deadReckoning: {
      algorithm: dr.deadReckoningAlgorithm,
      other: (version === 7 ? dr.parameters : dr.otherParameters).map(u8),
      acceleration: vec(dr.entityLinearAcceleration),
      angularVelocity: vec(dr.entityAngularVelocity),
    },
    marking: {characterSet: p.marking.characterSet, chars: p.marking.characters.map(u8), text: p.marking.getMarking()},
    capabilities: u32(p.capabilities),
    parameters: records.map((r) => r.record),
  };
}

function warfareIds(p) {
  return {
    firing: id(p.firingEntityID),
    target: id(p.targetEntityID),
    munition: id(version === 7 ? (p.munitionExpendibleID || p.explodingEntityID) : p.munitionID),
    event: eventId(p.eventID),
  };
}

function fire(p, raw) {
  raw.fireMissionIndex = p.fireMissionIndex;
  return Object.assign(warfareIds(p), {
    fireMissionIndex: u32(p.fireMissionIndex),
    location: vec(p.locationInWorldCoordinates),
    descriptor: descriptor(version === 7 ? p.descriptor : p.burstDescriptor),
    velocity: vec(p.velocity),
    range: version === 7 ? p.range : p.rangeToTarget,
  });
}

function detonation(p, raw) {
  const records = (version === 7 ? p.variableParameters : p.articulationParameters).map(record);
  raw.recordCount = version === 7 ? p.numberOfVariableParameters : p.numberOfArticulationParameters;
  raw.records = records.map((r) => r.raw);
  return Object.assign(warfareIds(p), {
    velocity: vec(p.velocity),
    location: vec(p.locationInWorldCoordinates),
    descriptor: descriptor(version === 7 ? p.descriptor : p.burstDescriptor),
    entityLocation: vec(version === 7 ? p.locationOfEntityCoordinates : p.locationInEntityCoordinates),
    result: p.detonationResult,
    parameters: records.map((r) => r.record),
  });
}

const pdus = files.map((file) => {
  const bytes = fs.readFileSync(file);
  const p = factory.createPdu(bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.length));
  const raw = {padding: p.padding};  // version 7: byte 11; version 6: bytes 10-11
  const out = {file, header: header(p)};
  if (p.pduType === 1) out.entityState = entityState(p, raw);
  else if (p.pduType === 2) out.fire = fire(p, raw);
  else if (p.pduType === 3) out.detonation = detonation(p, raw);
  else throw new Error(file + ': PDU type ' + p.pduType + ' is not one this check reads');
  out.raw = raw;
  return out;
});
process.stdout.write(JSON.stringify({version, pdus}, null, 1) + '\n');
