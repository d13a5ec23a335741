#!/usr/bin/env python3
"""The nuScenes devkit's table loading, timed: the peer of bench_nuscenes BM_Load.

This reproduces the table loading of nuscenes-devkit 1.2.0 (github.com/nutonomy/nuscenes-devkit,
commit d9de17a, python-sdk/nuscenes/nuscenes.py; Apache-2.0, Copyright 2021 Motional) line for
line, because the devkit itself is not installable here (no PyPI; NuScenes.__init__ imports
sklearn, pyquaternion, tqdm, shapely, which Debian's python lacks):
  - nuscenes.py lines 72-84: the 13 tables, each through __load_table__ (lines 137-141:
    open + json.load);
  - nuscenes.py lines 153-208: __make_reverse_index__, every statement (token -> index dicts,
    category_name, sensor_modality / channel, sample data / anns, log map_token).
Left out, as they do no table work: the colormap (a constant dict), the lidarseg / panoptic /
image_annotations tables (absent from these versions), MapMask(...) per map record (lines 118-119:
an os.path.exists assert; the PNG is read only on use) and NuScenesExplorer(self) (stores self).

  /usr/bin/python3 bench/nuscenes_devkit_tables.py DATAROOT VERSION [REPS]

Prints one JSON line: rows, best wall seconds of REPS loads, the process CPU seconds of that load,
and the process peak RSS (MB, ru_maxrss; includes every load of this process, so use REPS=1 for
memory figures).
"""

import json
import os.path as osp
import resource
import sys
import time


class DevkitTables:
    """NuScenes.__init__ (devkit 1.2.0) up to the reverse index, without the map images."""

    def __init__(self, version, dataroot):
        self.version = version
        self.dataroot = dataroot
        self.table_names = ['category', 'attribute', 'visibility', 'instance', 'sensor',
                            'calibrated_sensor', 'ego_pose', 'log', 'scene', 'sample',
                            'sample_data', 'sample_annotation', 'map']
        assert osp.exists(self.table_root), 'Database version not found: {}'.format(self.table_root)
        # nuscenes.py lines 72-84.
        self.category = self.__load_table__('category')
        self.attribute = self.__load_table__('attribute')
        self.visibility = self.__load_table__('visibility')
        self.instance = self.__load_table__('instance')
        self.sensor = self.__load_table__('sensor')
        self.calibrated_sensor = self.__load_table__('calibrated_sensor')
        self.ego_pose = self.__load_table__('ego_pose')
        self.log = self.__load_table__('log')
        self.scene = self.__load_table__('scene')
        self.sample = self.__load_table__('sample')
        self.sample_data = self.__load_table__('sample_data')
        self.sample_annotation = self.__load_table__('sample_annotation')
        self.map = self.__load_table__('map')
        self.__make_reverse_index__()

    @property
    def table_root(self):
        return osp.join(self.dataroot, self.version)

    def __load_table__(self, table_name):
        """nuscenes.py lines 137-141."""
        with open(osp.join(self.table_root, '{}.json'.format(table_name))) as f:
            table = json.load(f)
        return table

    def __make_reverse_index__(self):
        """nuscenes.py lines 153-208, without the verbose prints."""
        self._token2ind = dict()
        for table in self.table_names:
            self._token2ind[table] = dict()
            for ind, member in enumerate(getattr(self, table)):
                self._token2ind[table][member['token']] = ind

        for record in self.sample_annotation:
            inst = self.get('instance', record['instance_token'])
            record['category_name'] = self.get('category', inst['category_token'])['name']

        for record in self.sample_data:
            cs_record = self.get('calibrated_sensor', record['calibrated_sensor_token'])
            sensor_record = self.get('sensor', cs_record['sensor_token'])
            record['sensor_modality'] = sensor_record['modality']
            record['channel'] = sensor_record['channel']

        for record in self.sample:
            record['data'] = {}
            record['anns'] = []

        for record in self.sample_data:
            if record['is_key_frame']:
                sample_record = self.get('sample', record['sample_token'])
                sample_record['data'][record['channel']] = record['token']

        for ann_record in self.sample_annotation:
            sample_record = self.get('sample', ann_record['sample_token'])
            sample_record['anns'].append(ann_record['token'])

        if 'log_tokens' not in self.map[0].keys():
            raise Exception('Error: log_tokens not in map table.')
        log_to_map = dict()
        for map_record in self.map:
            for log_token in map_record['log_tokens']:
                log_to_map[log_token] = map_record['token']
        for log_record in self.log:
            log_record['map_token'] = log_to_map[log_record['token']]

    def get(self, table_name, token):
        """nuscenes.py lines 210-219 (get) and 221-228 (getind)."""
        assert table_name in self.table_names, "Table {} not found".format(table_name)
        return getattr(self, table_name)[self._token2ind[table_name][token]]


def main():
    dataroot, version = sys.argv[1], sys.argv[2]
    reps = int(sys.argv[3]) if len(sys.argv) > 3 else 1
    best_wall, best_cpu, rows = float('inf'), 0.0, 0
    for _ in range(reps):
        wall0, cpu0 = time.perf_counter(), time.process_time()
        nusc = DevkitTables(version, dataroot)
        wall, cpu = time.perf_counter() - wall0, time.process_time() - cpu0
        rows = len(nusc.sample_data)
        del nusc
        if wall < best_wall:
            best_wall, best_cpu = wall, cpu
    rss_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(json.dumps({'sample_data': rows, 'wall_s': best_wall, 'cpu_s': best_cpu,
                      'peak_rss_mb': rss_mb, 'reps': reps, 'python': sys.version.split()[0]}))


if __name__ == '__main__':
    main()
