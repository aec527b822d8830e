// Sends PDU files over UDP with Node's dgram, one datagram each, in order:
// Open-DIS's PDUs (write_pdus.js) to a Sandtable receiver on loopback
// (test_opendis.cpp, OpenDis.*OverUdp).
//
//   node send_pdus.js ADDRESS PORT FILE...
'use strict';

const dgram = require('dgram');
const fs = require('fs');

const [address, portText, ...files] = process.argv.slice(2);
const port = Number(portText);
if (!address || !(port > 0 && port < 65536) || files.length === 0) {
  throw new Error('usage: node send_pdus.js ADDRESS PORT FILE...');
}
const socket = dgram.createSocket('udp4');
let next = 0;
function sendNext(error) {
  if (error) throw error;
  if (next === files.length) {
    socket.close();
    return;
  }
  socket.send(fs.readFileSync(files[next++]), port, address, sendNext);
}
sendNext(null);
