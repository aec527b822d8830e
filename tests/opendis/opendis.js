// Shared by write_pdus.js, read_pdus.js and exercise.js: loading one
// Open-DIS build, setting the fields whose names differ between its two
// builds, and the bit conversions its record classes need (docs/DIS.md §10).
//
// One build per process: both dist files assign a global `dis` and their
// classes set their prototypes from that global when constructed, so a
// process that loaded dis6 and dis7 would mix the two.
'use strict';

/** The Open-DIS for JavaScript build of DIS `version` (6 or 7). */
function load(version) {
  if (version === 6) return require('open-dis');  // package.json main: dist/dis6.min.js
  if (version === 7) return require('open-dis/dist/dis7.min.js');
  throw new Error('opendis: version ' + version + ' is not 6 or 7');
}

/** The version named on the command line, 6 or 7. */
function versionArg(text) {
  const v = Number(text);
  if (v !== 6 && v !== 7) throw new Error('opendis: version "' + text + '" is not 6 or 7');
  return v;
}

/** Setters for the fields whose names differ between the builds of
 * `version`: ids [site, application, entity], event ids, entity types
 * (7 numbers), vectors [x, y, z] and munition descriptors. */
function fields(version) {
  function setId(target, v) {
    if (version === 7) {
      target.siteID = v[0];
      target.applicationID = v[1];
      target.entityID = v[2];
    } else {
      target.site = v[0];
      target.application = v[1];
      target.entity = v[2];
    }
  }
  function setEventId(target, v) {
    if (version === 7) {
      target.simulationAddress.site = v[0];
      target.simulationAddress.application = v[1];
    } else {
      target.site = v[0];
      target.application = v[1];
    }
    target.eventNumber = v[2];
  }
  function setType(target, t) {
    target.entityKind = t[0];
    target.domain = t[1];
    target.country = t[2];
    target.category = t[3];
    target.subcategory = t[4];
    if (version === 7) target.specific = t[5];
    else target.spec = t[5];
    target.extra = t[6];
  }
  function setVec(target, v) {
    target.x = v[0];
    target.y = v[1];
    target.z = v[2];
  }
  function setDescriptor(target, d) {
    setType(version === 7 ? target.munitionType : target.munition, d.munition);
    target.warhead = d.warhead;
    target.fuse = d.fuse;
    target.quantity = d.quantity;
    target.rate = d.rate;
  }
  return {setId, setEventId, setType, setVec, setDescriptor};
}

const scratch = new DataView(new ArrayBuffer(8));

/** The 8 big-endian bytes of a record's value field holding a float32
 * followed by 32 bits of zero padding (the standard's articulated part). */
function float32Field(value) {
  scratch.setFloat32(0, value);
  scratch.setUint32(4, 0);
  return bytes8();
}

/** The 8 bytes of an entity type (kind, domain, country u16, category,
 * subcategory, specific, extra): the attached part's value field. */
function entityTypeField(t) {
  scratch.setUint8(0, t[0]);
  scratch.setUint8(1, t[1]);
  scratch.setUint16(2, t[2]);
  for (let k = 3; k < 7; ++k) scratch.setUint8(k + 1, t[k]);
  return bytes8();
}

function bytes8() {
  const out = [];
  for (let k = 0; k < 8; ++k) out.push(scratch.getUint8(k));
  return out;
}

/** Open-DIS 6's ArticulationParameter.parameterValue (a float64) that puts
 * `field` (8 bytes) on the wire. */
function asFloat64(field) {
  field.forEach((b, k) => scratch.setUint8(k, b));
  return scratch.getFloat64(0);
}

/** Open-DIS 7's ArticulatedParts/AttachedParts.parameterValue (a signed
 * 64-bit integer as a decimal string, which its writeLong parses) that
 * puts `field` on the wire. */
function asLongString(field) {
  let u = 0n;
  for (const b of field) u = (u << 8n) | BigInt(b);
  return BigInt.asIntN(64, u).toString();
}

/** The 8 wire bytes of an Open-DIS 6 float64 value. */
function fromFloat64(value) {
  scratch.setFloat64(0, value);
  return bytes8();
}

/** The 8 wire bytes of an Open-DIS 7 64-bit value (decimal string). */
function fromLongString(text) {
  let u = BigInt.asUintN(64, BigInt(text));
  const out = [];
  for (let k = 0; k < 8; ++k) {
    out.unshift(Number(u & 0xffn));
    u >>= 8n;
  }
  return out;
}

/** The float32 in the first 4 of 8 field bytes, and the other 4 as u32. */
function float32OfField(field) {
  field.forEach((b, k) => scratch.setUint8(k, b));
  return {value: scratch.getFloat32(0), padding: scratch.getUint32(4)};
}

/** The entity type in 8 field bytes, as the 7 numbers. */
function entityTypeOfField(field) {
  field.forEach((b, k) => scratch.setUint8(k, b));
  return [scratch.getUint8(0), scratch.getUint8(1), scratch.getUint16(2), scratch.getUint8(4), scratch.getUint8(5),
          scratch.getUint8(6), scratch.getUint8(7)];
}

module.exports = {
  load, versionArg, fields, float32Field, entityTypeField, asFloat64, asLongString, fromFloat64, fromLongString,
  float32OfField, entityTypeOfField,
};
