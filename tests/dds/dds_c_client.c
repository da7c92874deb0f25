/* A simgate DDS client in plain C (the example of docs/transports/dds.md, built and run by
   DdsCClientTest).  usage: dds_c_client DOMAIN PARTITION COMPONENT SERVICE PARAMS_JSON [XML] */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <dds/dds.h>
#include "simgate_dds.h" /* idlc simgate_dds.idl */

int main(int argc, char** argv) { /* DOMAIN PARTITION COMPONENT SERVICE PARAMS_JSON [XML] */
  if (argc < 6) return 2;
  dds_domainid_t domain = (dds_domainid_t)atoi(argv[1]);
  dds_entity_t dom = dds_create_domain(domain, argc > 6 ? argv[6] : NULL);
  dds_entity_t pp = dds_create_participant(domain, NULL, NULL);
  dds_qos_t *q = dds_create_qos(), *rq_part = dds_create_qos();
  dds_qset_partition1(q, argv[2]);
  dds_entity_t pub = dds_create_publisher(pp, q, NULL);
  dds_qset_reliability(q, DDS_RELIABILITY_RELIABLE, DDS_SECS(1));
  dds_qset_history(q, DDS_HISTORY_KEEP_ALL, 0);
  dds_entity_t wr = dds_create_writer(
      pub, dds_create_topic(pp, &simgate_Request_desc, "simgate_Request", NULL, NULL), q, NULL);
  dds_guid_t me; /* our id: the request writer's GUID (the server refuses any other) */
  dds_get_guid(wr, &me);
  char ud[64] = "simgate.id=", part[400]; /* announced in the reply reader's USER_DATA */
  for (int i = 0; i < 16; i++) sprintf(ud + 11 + 2 * i, "%02x", me.v[i]);
  dds_qset_userdata(q, ud, strlen(ud));
  snprintf(part, sizeof part, "%s/%s", argv[2], ud + 11),
      dds_qset_partition1(rq_part, part); /* our replies' partition */
  dds_entity_t rd = dds_create_reader(
      dds_create_subscriber(pp, rq_part, NULL),
      dds_create_topic(pp, &simgate_Reply_desc, "simgate_Reply", NULL, NULL), q, NULL);
  const char* uri =
      getenv("CYCLONEDDS_URI"); /* found only with the same domain, partition and network config */
  fprintf(stderr,
          "waiting for simgate in domain %u, partition '%s' (%s%s; the simulation must use the "
          "same)...\n",
          (unsigned)domain, argv[2],
          argc > 6 ? "network config: the XML argument"
          : uri    ? "CYCLONEDDS_URI="
                   : "CYCLONEDDS_URI is not set: Cyclone uses its default network config",
          argc > 6 || !uri ? "" : uri);
  dds_publication_matched_status_t m = {
      0}; /* wait (10 s at most) for the simulation's request reader */
  for (int i = 0; i < 1000 && m.current_count == 0; i++, dds_sleepfor(DDS_MSECS(10)))
    dds_get_publication_matched_status(wr, &m);
  if (m.current_count ==
      0) { /* simgate's dds transport is on loopback unless its "config" says otherwise */
    fprintf(stderr,
            "no simgate found within 10 s (for a simulation on loopback: config/dds/loopback.xml "
            "as XML)\n");
    dds_delete_qos(q), dds_delete_qos(rq_part);
    dds_delete(dom > 0 ? dom : pp);
    return 3;
  }
  simgate_Request rq = {
      .op = simgate_OP_CALL, .component = argv[3], .service = argv[4], .params = argv[5]};
  memcpy(rq.id.client, me.v, 16);
  rq.id.seq = 1;
  dds_write(wr, &rq);
  int status = -1; /* replies for our seq: ST_ACCEPTED (async), then the last one */
  for (int i = 0; i < 6000 && status < 0; i++, dds_sleepfor(DDS_MSECS(10))) {
    void* s[1] = {NULL};
    dds_sample_info_t si;
    while (status < 0 && dds_take(rd, s, &si, 1, 1) == 1) {
      const simgate_Reply* r = s[0];
      if (si.valid_data && memcmp(r->client, me.v, 16) == 0 && r->seq == 1 && r->last) {
        printf("%s %s%s\n", r->status == simgate_ST_SUCCESS ? "SUCCESS" : "FAILED/PREEMPTED",
               r->result, r->message);
        status = r->status == simgate_ST_SUCCESS ? 0 : 1;
      }
      dds_return_loan(rd, s, 1);
    }
  }
  if (status < 0) fprintf(stderr, "no reply from simgate within 60 s\n");
  dds_delete_qos(q), dds_delete_qos(rq_part);
  dds_delete(dom > 0 ? dom : pp);
  return status < 0 ? 3 : status;
}
