#!/usr/bin/env bash
# Generates what a Facetscan fleet's nats-server needs (docs/fleet.md#security), with openssl only:
#   OUTDIR/ca.pem, ca-key.pem            a private CA (EC P-256, 10 years); ca-key.pem stays on this machine
#   OUTDIR/server-cert.pem, server-key.pem  the server's certificate for localhost, 127.0.0.1, ::1 and every
#                                        HOST / IP given (cluster nodes: give each node's name and address)
#   OUTDIR/passwords.env                 random passwords of the users admin, gateway, worker, shopfloor, client
#                                        (FACETSCAN_*_PASSWORD=...; kept if it exists)
# Usage: gen-certs.sh OUTDIR [HOST|IP ...]     e.g. gen-certs.sh /etc/facetscan/nats nats1.plant 10.0.0.5
# Existing CA files are reused (new server certificates from the same CA); delete OUTDIR to start over.
set -euo pipefail

if [ $# -lt 1 ]; then
  echo "usage: $0 OUTDIR [HOST|IP ...]" >&2
  exit 2
fi
out=$1
shift
mkdir -p "$out"
umask 077

san="DNS:localhost,IP:127.0.0.1,IP:::1"
for name in "$@"; do
  if [[ $name =~ ^[0-9.]+$ || $name == *:* ]]; then san+=",IP:$name"; else san+=",DNS:$name"; fi
done

if [ ! -f "$out/ca.pem" ] || [ ! -f "$out/ca-key.pem" ]; then
  openssl req -x509 -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -days 3650 \
    -subj "/CN=Facetscan fleet CA" -keyout "$out/ca-key.pem" -out "$out/ca.pem" \
    -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" 2>/dev/null
fi

openssl req -newkey ec -pkeyopt ec_paramgen_curve:prime256v1 -nodes -subj "/CN=facetscan-nats" \
  -keyout "$out/server-key.pem" -out "$out/server.csr" 2>/dev/null
ext=$(mktemp)
trap 'rm -f "$ext"' EXIT
printf 'subjectAltName=%s\nextendedKeyUsage=serverAuth,clientAuth\nkeyUsage=critical,digitalSignature\n' \
  "$san" >"$ext"
openssl x509 -req -in "$out/server.csr" -CA "$out/ca.pem" -CAkey "$out/ca-key.pem" -CAcreateserial \
  -days 825 -extfile "$ext" -out "$out/server-cert.pem" 2>/dev/null
rm -f "$out/server.csr"

if [ ! -f "$out/passwords.env" ]; then
  {
    # nats-server parses an environment variable's value as a config value: hex starting with a digit would be
    # read as a number (and "1e5..." as a float), so every password starts with letters.
    for user in ADMIN GATEWAY WORKER SHOPFLOOR CLIENT; do
      echo "FACETSCAN_${user}_PASSWORD=pw$(openssl rand -hex 16)"
    done
  } >"$out/passwords.env"
fi
chmod 600 "$out"/*-key.pem "$out/passwords.env"
chmod 644 "$out/ca.pem" "$out/server-cert.pem"
echo "gen-certs: $out: ca.pem, server-cert.pem ($san), passwords.env"
