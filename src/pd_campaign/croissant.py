"""The labelled dataset's description in MLCommons Croissant 1.0 (JSON-LD), croissant.json beside
the data (doc/dataset.md, "Croissant"): what the dataset is, its licence and version, how to cite
it, its files with their SHA-256, one record set per split and table with every field's type,
unit, frame and meaning, the layer labels as an enumeration, and the responsible-AI fields
(Croissant RAI 1.0: how the data were made, what the simulation leaves out, biases, personal
information, uses, maintenance).

Croissant 1.0 has no extractor for HDF5: a field's `source` names the file and, as `column`,
the HDF5 path of its column (`/<split>/samples/<column>`). A Croissant reader validates the
description and the checksums; the records are read with h5py (doc/dataset.md, "Reading it")."""
import json
import os

from pd_campaign import dataset, dataset_files
from pd_campaign.atomic import atomic_write

CONFORMS_TO = 'http://mlcommons.org/croissant/1.0'
# The Croissant 1.0 context (as in the specification's examples) with the RAI namespace.
CONTEXT = {
    '@language': 'en', '@vocab': 'https://schema.org/', 'sc': 'https://schema.org/',
    'cr': 'http://mlcommons.org/croissant/', 'rai': 'http://mlcommons.org/croissant/RAI/',
    'dct': 'http://purl.org/dc/terms/', 'citeAs': 'cr:citeAs', 'column': 'cr:column',
    'conformsTo': 'dct:conformsTo', 'data': {'@id': 'cr:data', '@type': '@json'},
    'dataType': {'@id': 'cr:dataType', '@type': '@vocab'},
    'examples': {'@id': 'cr:examples', '@type': '@json'}, 'extract': 'cr:extract',
    'field': 'cr:field', 'fileProperty': 'cr:fileProperty', 'fileObject': 'cr:fileObject',
    'fileSet': 'cr:fileSet', 'format': 'cr:format', 'includes': 'cr:includes',
    'isLiveDataset': 'cr:isLiveDataset', 'jsonPath': 'cr:jsonPath', 'key': 'cr:key',
    'md5': 'cr:md5', 'parentField': 'cr:parentField', 'path': 'cr:path',
    'recordSet': 'cr:recordSet', 'references': 'cr:references', 'regex': 'cr:regex',
    'repeated': 'cr:repeated', 'replace': 'cr:replace', 'separator': 'cr:separator',
    'source': 'cr:source', 'subField': 'cr:subField', 'transform': 'cr:transform',
}
# NumPy kind (or 'text') -> Croissant data type.
DATA_TYPES = {'f': 'sc:Float', 'i': 'sc:Integer', 'u': 'sc:Integer', 'b': 'sc:Boolean',
              'text': 'sc:Text'}
FILE_DESCRIPTIONS = {
    dataset_files.HDF5_NAME: 'every split\'s samples and trial tables as columns, with the units, '
    'frames, meanings and the dataset\'s metadata as HDF5 attributes',
    'split.json': 'each split\'s trial ids and seeds; the base seed, scenario and protocol',
    dataset_files.DATASHEET_NAME: 'the datasheet: fields, units, counts, how it was made, limits',
}
NAME = 'pedicle-drilling-force-dataset'


def field_description(unit, frame, meaning):
    """A field's description: its meaning, unit and frame (dataset.FRAMES)."""
    return '%s. Unit: %s. Frame: %s.' % (meaning[0].upper() + meaning[1:], unit, frame)


def _field(record, name, kind, description, split, table):
    return {'@type': 'cr:Field', '@id': '%s/%s' % (record, name), 'name': name,
            'description': description, 'dataType': DATA_TYPES[kind],
            'source': {'fileObject': {'@id': dataset_files.HDF5_NAME},
                       'extract': {'column': '/%s/%s/%s' % (split, table, name)}}}


def layers_record_set():
    """The layer labels as a Croissant enumeration, its records inline."""
    fields = [{'@type': 'cr:Field', '@id': 'layers/' + name, 'name': name, 'description': text,
               'dataType': data_type}
              for name, data_type, text in (('label', 'sc:Integer', 'the value of `layer`'),
                                            ('name', 'sc:Text', 'the layer\'s name'),
                                            ('meaning', 'sc:Text', 'what the label says'))]
    return {'@type': 'cr:RecordSet', '@id': 'layers', 'name': 'layers',
            'description': 'The labels of the per-sample `layer` column: the material at the '
                           'deepest cut.',
            'dataType': 'sc:Enumeration', 'key': {'@id': 'layers/label'}, 'field': fields,
            'data': [{'layers/label': k, 'layers/name': name, 'layers/meaning': meaning}
                     for k, (name, meaning) in enumerate(zip(dataset.LAYERS,
                                                             dataset.LAYER_MEANINGS))]}


def record_sets(columns):
    """The layer enumeration and, per split, its samples and trials record sets; `columns`:
    dataset_files.Hdf5Writer.columns (each column's name and kind, in file order)."""
    declared = {
        'samples': {name: (unit, frame, meaning) for name, unit, frame, meaning
                    in dataset.SAMPLE_FIELDS + [dataset.TRIAL_COLUMN]},
        'trials': {name: (unit, frame, meaning) for name, _, unit, frame, meaning
                   in dataset.TRIAL_FIELDS + dataset.TRIAL_INDEX_FIELDS}}
    what = {'samples': 'one record per force-sensor sample', 'trials': 'one record per trial'}
    sets = [layers_record_set()]
    for split in dataset.SPLITS:
        for table in ('samples', 'trials'):
            record = '%s_%s' % (split, table)
            fields = [_field(record, name, kind, field_description(*declared[table][name]),
                             split, table) for name, kind in columns[split][table]]
            entry = {'@type': 'cr:RecordSet', '@id': record, 'name': record,
                     'description': 'The %s split, %s (HDF5 group /%s/%s).' % (
                         split, what[table], split, table), 'field': fields}
            if table == 'trials':
                entry['key'] = {'@id': record + '/trial_id'}
            else:
                layer = next(f for f in fields if f['name'] == 'layer')
                layer['references'] = {'field': {'@id': 'layers/label'}}
            sets.append(entry)
    return sets


def distribution(out_dir):
    """A FileObject per file of the dataset (not croissant.json itself), with its SHA-256."""
    files = []
    for name, media_type in dataset_files.MEDIA_TYPES:
        path = os.path.join(out_dir, name)
        files.append({
            '@type': 'cr:FileObject', '@id': name, 'name': name,
            'description': FILE_DESCRIPTIONS.get(name, 'the %s split as a NumPy .npz archive of '
                                                 'the same columns' % name.split('.')[0]),
            'contentUrl': name, 'contentSize': '%d B' % os.path.getsize(path),
            'encodingFormat': media_type, 'sha256': dataset_files.sha256_of(path)})
    return files


def cite_as(meta, version):
    package = meta['package']
    return ('@misc{pedicle_drilling_force_dataset,\n'
            '  title = {%s},\n  author = {{%s}},\n  version = {%s},\n'
            '  note = {Written by campaign\\_dataset of %s %s (build %s), scenario %s, base seed '
            '%d}\n}' % (dataset_files.TITLE, package['maintainer'], version, package['name'],
                        package['version'], package['build_id'], meta['scenario'],
                        meta['base_seed']))


def rai_fields(meta, counts):
    """The Croissant RAI 1.0 fields of the dataset."""
    physics = dataset_files.SIMULATOR_PHYSICS
    total = sum(counts[split]['trials'] for split in dataset.SPLITS)
    return {
        'rai:dataCollection': (
            'Simulated closed-loop trials of the package\'s core engine (`campaign --samples`), '
            'the paper\'s peak-force protocol: the paper\'s recognizer observes and every trial '
            'drills through the inner cortical layer, so each trial holds every layer. %d trials '
            'of the scenario %s, base seed %d; one seed gives the same trial bit for bit. The '
            'force model, sensor chain, specimens and patients are those of %s.'
            % (total, meta['scenario'], meta['base_seed'], physics)),
        'rai:dataCollectionType': ['Simulation (software-generated, nothing measured)'],
        'rai:dataPreprocessingProtocol': (
            'None beyond the simulated sensor chain (tare, DAQ rate, noise, resolution, faults '
            'as configured): samples are recorded as the engine made them; trials that failed '
            'to run are left out.'),
        'rai:annotationProtocol': (
            'No human annotation: `layer` is the simulator\'s ground truth, the material at the '
            'deepest point cut.'),
        'rai:dataLimitations': dataset_files.LIMITATIONS + (
            ' A recognizer that does well here has passed a necessary test, not a sufficient '
            'one.'),
        'rai:dataBiases': (
            'The specimens, patients and noise are drawn from the distributions of %s (sections '
            '1, 3 and 6), several of them assumptions; one drill, one feed rate, one bone model '
            'family and the paper\'s bench. The split is by seed, never by outcome: train and '
            'validation come from the calibration seed space, test from the evaluation seed '
            'space, so no constant was chosen on the test trials.' % physics),
        'rai:personalSensitiveInformation': (
            'None: every trial is simulated; the breathing patients are virtual volunteers drawn '
            'from distributions, not records of people.'),
        'rai:dataUseCases': (
            'Training, tuning and offline evaluation of force-based drilling-state recognizers '
            '(train: fit; validation: choose settings; test: report). Not a substitute for '
            'bench or clinical validation.'),
        'rai:dataSocialImpact': (
            'Meant to make recognizers comparable before any bench test; a recognizer\'s score '
            'here says nothing of its safety on patients.'),
        'rai:dataReleaseMaintenance': MAINTENANCE,
    }


MAINTENANCE = (
    'Regenerated, not edited: `rosrun pedicle_drilling campaign_dataset` writes it from the '
    'package, the same command giving the same values. The version is the format version '
    '(semantic versioning, bumped by hand when a column changes) and, after "+", the first 12 '
    'digits of the content hash: it changes whenever a value does. Maintained with the '
    'package by its maintainers (package.xml); doc/dataset.md of the package says how.')


def croissant(out_dir, meta, counts, writer):
    """The Croissant description (a dict) of the dataset in `out_dir`, whose HDF5 file
    `writer` (a finished dataset_files.Hdf5Writer) wrote."""
    package = meta['package']
    samples = sum(counts[split]['samples'] for split in dataset.SPLITS)
    description = '%s %s' % (dataset_files.DESCRIPTION, 'This copy: %s; %d samples.' % (
        ', '.join('%s %d trials' % (split, counts[split]['trials'])
                  for split in dataset.SPLITS), samples))
    document = {
        '@context': CONTEXT, '@type': 'sc:Dataset', 'conformsTo': CONFORMS_TO, 'name': NAME,
        'description': description, 'license': dataset_files.SPDX_URL % package['license'],
        'version': writer.version, 'citeAs': cite_as(meta, writer.version),
        'creator': {'@type': 'sc:Organization', 'name': package['maintainer']},
        'keywords': ['pedicle drilling', 'force sensing', 'drilling-state recognition',
                     'robot-assisted surgery', 'simulation', 'time series'],
        'isLiveDataset': False,
        'distribution': distribution(out_dir), 'recordSet': record_sets(writer.columns)}
    document.update(rai_fields(meta, counts))
    return document


def write(out_dir, meta, counts, writer):
    """croissant.json in `out_dir`."""
    with atomic_write(os.path.join(out_dir, dataset_files.CROISSANT_NAME)) as handle:
        json.dump(croissant(out_dir, meta, counts, writer), handle, indent=1)
        handle.write('\n')
