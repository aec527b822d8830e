// Decodes Point and Linear Object State PDU files (DIS 7) with Open-DIS for
// JavaScript (npm open-dis 1.3.6, dist/dis7.min.js) and prints every field
// as JSON; tests/opendis/test_opendis_objects.cpp compares them with the
// terrain edits Sandtable sent (docs/DIS.md §14).
//
//   node read_objects.js FILE...
//
// Prints {"pdus": [{"file", "via", "header", "object"}]}:
// - type 43 goes through Open-DIS's own PduFactory ("via": "factory");
// - type 44 has no case in that factory (it throws "Unrecognized PDUType"),
//   so it is read with the package's LinearObjectStatePdu class directly
//   ("via": "class"), as an Open-DIS user must;
// - every location also as lon, lat and height by Open-DIS's own
//   CoordinateConversion.convertDisToLatLongInDegrees: nothing of ours.
'use strict';

const fs = require('fs');
const od = require('./opendis.js');

const dis = od.load(7);
const factory = new dis.PduFactory();
const convert = new dis.CoordinateConversion();

const id = (e) => [e.siteID, e.applicationID, e.entityID];
const address = (a) => [a.site, a.application];
const vec = (v) => [v.x, v.y, v.z];
const euler = (e) => [e.psi, e.theta, e.phi];
const type = (t) => [t.domain, t.objectKind, t.category, t.subcategory];
function geodetic(v) {
  const g = convert.convertDisToLatLongInDegrees({x: v.x, y: v.y, z: v.z});
  return [g.longitude, g.latitude, g.altitude];
}

function header(p) {
  return {version: p.protocolVersion, exercise: p.exerciseID, type: p.pduType, family: p.protocolFamily,
          timestamp: p.timestamp, length: p.length, status: p.pduStatus};
}

function point(p) {
  return {id: id(p.objectID), referenced: id(p.referencedObjectID), updateNumber: p.updateNumber,
          force: p.forceID, modifications: p.modifications, type: type(p.objectType),
          location: vec(p.objectLocation), geodetic: geodetic(p.objectLocation),
          orientation: euler(p.objectOrientation), appearance: p.objectAppearance,
          requester: address(p.requesterID), receiver: address(p.receivingID)};
}

function linear(p) {
  return {id: id(p.objectID), referenced: id(p.referencedObjectID), updateNumber: p.updateNumber,
          force: p.forceID, segmentCount: p.numberOfSegments, requester: address(p.requesterID),
          receiver: address(p.receivingID), type: type(p.objectType),
          segments: p.linearSegmentParameters.map((s) => ({
            number: s.segmentNumber, modification: s.segmentModification,
            general: s.generalSegmentAppearance, specific: s.specificSegmentAppearance,
            location: vec(s.segmentLocation), geodetic: geodetic(s.segmentLocation),
            orientation: euler(s.segmentOrientation), length: s.segmentLength, width: s.segmentWidth,
            height: s.segmentHeight, depth: s.segmentDepth}))};
}

const pdus = process.argv.slice(2).map((file) => {
  const bytes = fs.readFileSync(file);
  const buffer = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.length);
  if (bytes[2] === 43) {
    const p = factory.createPdu(buffer);
    return {file, via: 'factory', header: header(p), object: point(p)};
  }
  if (bytes[2] === 44) {
    const p = new dis.LinearObjectStatePdu();
    p.initFromBinary(new dis.InputStream(buffer));
    return {file, via: 'class', header: header(p), object: linear(p)};
  }
  throw new Error(file + ': PDU type ' + bytes[2] + ' is not an object this check reads');
});
process.stdout.write(JSON.stringify({pdus}, null, 1) + '\n');
