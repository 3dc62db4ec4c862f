!> Readers of the groups that describe the body: &geometry, &material and &damping.
module iem_input_body
  use iem_kinds, only: wp
  use iem_constants, only: unset_real, unset_int
  use iem_strings, only: itoa, rtoa, lower
  use iem_config, only: config_t, material_config_t, name_len, path_len
  use iem_namelist_text, only: nml_text_t, line_len
  use iem_input_checks, only: bad, given
  use iem_input_table, only: key_t, key, key_only, read_group, check_literals, check_values
  use iem_input_fracture, only: check_fracture_keys
  implicit none
  private
  public :: read_geometry, read_material, read_damping, max_levels

  !> Most grey levels of an image cell map (image_levels, image_materials).
  integer, parameter :: max_levels = 256
  !> What a name of image_materials holds when the input does not give it.
  character(len=*), parameter :: unset_name = achar(0)//'unset'

contains

  ! ----------------------------------------------------------------------------- &geometry
  subroutine parse_geometry(chunk, cfg, ios, iomsg, gaps)
    character(len=line_len), intent(in) :: chunk(:)
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: ios
    character(len=256), intent(out) :: iomsg
    !> Whether image_levels or image_materials has an empty value before a given one.
    logical, intent(out), optional :: gaps
    real(wp) :: length, height, thickness, cell_size
    integer :: nx, ny, image_levels(max_levels), nl, nm
    character(len=8) :: plane, cell, pieces
    character(len=name_len) :: background, image_materials(max_levels)
    character(len=path_len) :: image
    namelist /geometry/ length, height, thickness, nx, ny, cell_size, plane, cell, &
      background, image, image_levels, image_materials, pieces
    length = unset_real; height = unset_real; thickness = cfg%geometry%thickness
    nx = 0; ny = 0; cell_size = 0.0_wp; plane = cfg%geometry%plane; cell = cfg%geometry%cell
    background = ''; image = ''; image_levels = unset_int; image_materials = unset_name
    pieces = cfg%geometry%pieces
    iomsg = ''
    read(chunk, nml=geometry, iostat=ios, iomsg=iomsg)
    cfg%geometry%length = length; cfg%geometry%height = height
    cfg%geometry%thickness = thickness; cfg%geometry%nx = nx; cfg%geometry%ny = ny
    cfg%geometry%cell_size = cell_size; cfg%geometry%plane = lower(plane)
    cfg%geometry%cell = lower(cell)
    cfg%geometry%background = background; cfg%geometry%image = image
    cfg%geometry%pieces = lower(pieces)
    ! the values given are the leading ones; a null value (',,') before a given one is a gap
    nl = leading(image_levels /= unset_int)
    nm = leading(image_materials /= unset_name)
    cfg%geometry%image_levels = image_levels(1:nl)
    cfg%geometry%image_materials = image_materials(1:nm)
    allocate(cfg%geometry%image_material_ids(nm))
    cfg%geometry%image_material_ids = 0
    if (present(gaps)) gaps = count(image_levels /= unset_int) /= nl .or. &
                              count(image_materials /= unset_name) /= nm
  contains
    pure integer function leading(set) result(n)
      logical, intent(in) :: set(:)
      n = findloc(set, .false., 1) - 1
      if (n < 0) n = size(set)
    end function leading
  end subroutine parse_geometry

  !> Check, parse and validate group g (&geometry) of the input into the configuration.
  subroutine read_geometry(text, g, cfg, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(config_t), intent(inout), target :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=256) :: iomsg
    character(len=*), parameter :: label = '&geometry'
    type(key_t) :: keys(13)
    real(wp) :: nn
    logical :: gaps, has_image
    associate(o => cfg%geometry)
      keys = [key('length', o%length, need=' [m]', range='> 0', unit=' [m]'), &
        key('height', o%height, need=' [m]', range='> 0', unit=' [m]'), &
        key('thickness', o%thickness, range='> 0', unit=' [m]'), key('nx', o%nx), &
        key('ny', o%ny), key('cell_size', o%cell_size, range='> 0', &
                             unit=' [m] (or give nx, ny instead)'), &
        key('plane', o%plane, allowed='stress strain'), &
        key('cell', o%cell, allowed='paper bending'), key('background', o%background), &
        key('image', o%image), key_only('image_levels', 'i'), &
        key_only('image_materials', 's', name_len), &
        key('pieces', o%pieces, allowed='warn allow one')]
    end associate
    call read_group(text, g, keys, label, try_geometry, chunk, stat, msg)
    if (stat /= 0) return
    call parse_geometry(chunk, cfg, stat, iomsg, gaps)
    call check_values(keys, 'pieces', label, stat, msg)
    if (stat == 0) call check_fill(text, g, label, cfg, gaps, stat, msg)
    if (stat == 0 .and. given(text, g, 'cell_size')) call check_values(keys, 'cell_size', &
                                                                       label, stat, msg)
    if (stat == 0) call check_literals(text, g, keys, label, stat, msg)
    if (stat == 0) call check_values(keys, 'length height thickness plane cell', label, stat, &
                                     msg)
    if (stat /= 0) return
    has_image = len_trim(cfg%geometry%image) > 0
    associate(o => cfg%geometry)
      if (o%cell_size /= 0.0_wp .and. (o%nx /= 0 .or. o%ny /= 0)) then
        call bad(label, 'cell_size', rtoa(o%cell_size), 'cannot be combined with nx, ny', &
                 stat, msg)
      else if (.not. (o%cell_size >= 0.0_wp)) then
        call bad(label, 'cell_size', rtoa(o%cell_size), 'must be > 0 [m]', stat, msg)
      else if (o%cell_size == 0.0_wp .and. o%nx < 1 .and. .not. (has_image .and. o%nx == 0)) then
        call bad(label, 'nx', itoa(o%nx), 'must be >= 1 (or give cell_size or image)', stat, msg)
      else if (o%cell_size == 0.0_wp .and. o%ny < 1 .and. .not. (has_image .and. o%ny == 0)) then
        call bad(label, 'ny', itoa(o%ny), 'must be >= 1 (or give cell_size or image)', stat, msg)
      end if
      if (stat /= 0) return
      if (o%cell_size > 0.0_wp) then
        ! the counts are found in reals first: nint of a quotient above 2^31 is undefined
        if (max(o%length, o%height)/o%cell_size > 2.0e9_wp) then
          call bad(label, 'cell_size', rtoa(o%cell_size), 'gives '// &
                   rtoa(o%length/o%cell_size)//' x '//rtoa(o%height/o%cell_size)// &
                   ' cells: more than 2e9 along a side', stat, msg)
          return
        end if
        o%nx = max(1, nint(o%length/o%cell_size))
        o%ny = max(1, nint(o%height/o%cell_size))
      end if
      ! with an image the grid is known once the image is read (iem_input_image)
      nn = (real(o%nx, wp) + 1.0_wp)*(real(o%ny, wp) + 1.0_wp)
      if (nn > 2.0e9_wp .and. .not. has_image) then
        call bad(label, 'nx*ny', itoa(o%nx)//'*'//itoa(o%ny), &
                 'gives more than 2e9 nodes', stat, msg)
      end if
    end associate
  end subroutine read_geometry

  integer function try_geometry(part, iomsg) result(ios)
    character(len=line_len), intent(in) :: part(:)
    character(len=256), intent(out) :: iomsg
    type(config_t) :: c
    call parse_geometry(part, c, ios, iomsg)
  end function try_geometry

  !> Check what fills the grid: the image variables (only with image; levels
  !> >= 0 and distinct, one material each). Names are resolved in iem_input_scene, the image
  !> file itself is read in iem_input_image.
  subroutine check_fill(text, g, label, cfg, gaps, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    character(len=*), intent(in) :: label
    type(config_t), intent(inout) :: cfg
    logical, intent(in) :: gaps
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: k, j
    stat = 0
    msg = ''
    associate(o => cfg%geometry)
      if (len_trim(o%image) == 0) then
        if (given(text, g, 'image_levels')) then
          call bad(label, 'image_levels', '', 'applies only with image = a PBM/PGM file', &
                   stat, msg)
        else if (given(text, g, 'image_materials')) then
          call bad(label, 'image_materials', '', 'applies only with image = a PBM/PGM file', &
                   stat, msg)
        else if (given(text, g, 'image')) then
          call bad(label, 'image', "''", 'must name a PBM/PGM file (or leave image out)', &
                   stat, msg)
        end if
        return
      end if
      if (gaps) then
        call bad(label, 'image_levels, image_materials', '', 'have an empty value between '// &
                 'two given ones', stat, msg)
      else if (size(o%image_levels) == 0) then
        call bad(label, 'image_levels', '(not given)', 'is required with image: the grey '// &
                 'levels of the image (PBM: 0 white, 1 black)', stat, msg)
      else if (size(o%image_materials) /= size(o%image_levels)) then
        call bad(label, 'image_materials', itoa(size(o%image_materials))//' names', &
                 'must give one material (or ''void'') for each of the '// &
                 itoa(size(o%image_levels))//' image_levels', stat, msg)
      else
        do k = 1, size(o%image_levels)
          if (o%image_levels(k) < 0) then
            call bad(label, 'image_levels', itoa(o%image_levels(k)), 'must be >= 0 (a grey '// &
                     'level of the image)', stat, msg)
            return
          end if
          do j = 1, k - 1
            if (o%image_levels(j) == o%image_levels(k)) then
              call bad(label, 'image_levels', itoa(o%image_levels(k)), 'is given twice '// &
                       '(values '//itoa(j)//' and '//itoa(k)//')', stat, msg)
              return
            end if
          end do
        end do
      end if
    end associate
  end subroutine check_fill

  ! ----------------------------------------------------------------------------- &material
  subroutine parse_material(chunk, mat, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(material_config_t), intent(inout) :: mat
    integer, intent(out) :: ios
    character(len=256), intent(out) :: iomsg
    character(len=name_len) :: name
    real(wp) :: e, nu, density, tensile_strength, compressive_strength, shear_strength
    real(wp) :: tensile_failure_strain, compressive_failure_strain, shear_failure_strain
    real(wp) :: fracture_energy, crushing_energy, shear_fracture_energy
    logical :: nonlinear, fracture
    character(len=8) :: softening
    integer :: history_depth
    namelist /material/ name, e, nu, density, nonlinear, tensile_strength, &
      compressive_strength, shear_strength, history_depth, fracture, tensile_failure_strain, &
      compressive_failure_strain, shear_failure_strain, fracture_energy, crushing_energy, &
      shear_fracture_energy, softening
    name = ''; e = unset_real; nu = unset_real; density = unset_real
    nonlinear = mat%nonlinear; history_depth = mat%history_depth
    fracture = mat%fracture
    softening = ''
    tensile_strength = unset_real; compressive_strength = unset_real
    shear_strength = unset_real
    tensile_failure_strain = unset_real; compressive_failure_strain = unset_real
    shear_failure_strain = unset_real
    fracture_energy = unset_real; crushing_energy = unset_real; shear_fracture_energy = unset_real
    iomsg = ''
    read(chunk, nml=material, iostat=ios, iomsg=iomsg)
    mat%name = name
    mat%young = e; mat%poisson = nu; mat%density = density
    mat%nonlinear = nonlinear; mat%history_depth = history_depth
    mat%tensile_strength = tensile_strength
    mat%compressive_strength = compressive_strength
    mat%shear_strength = shear_strength
    mat%fracture = fracture
    mat%tensile_failure_strain = tensile_failure_strain
    mat%compressive_failure_strain = compressive_failure_strain
    mat%shear_failure_strain = shear_failure_strain
    mat%fracture_energy = fracture_energy
    mat%crushing_energy = crushing_energy
    mat%shear_fracture_energy = shear_fracture_energy
    mat%softening = lower(softening)
  end subroutine parse_material

  !> Check, parse and validate group g (one &material, called label in messages) into mat;
  !> the name is checked against the other materials later (iem_input_scene).
  subroutine read_material(text, g, label, mat, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    character(len=*), intent(in) :: label
    type(material_config_t), intent(inout), target :: mat
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=256) :: iomsg
    character(len=*), parameter :: with = ' with nonlinear = .true. [Pa]'
    type(key_t) :: keys(17)
    keys = [key('name', mat%name), key('e', mat%young, need=": Young's modulus [Pa]", &
                                       range='> 0', unit=' [Pa]', shown='E'), &
      key('nu', mat%poisson, need=": Poisson's ratio", range='(-1, 0.5)'), &
      key('density', mat%density, need=' [kg/m^3]', range='> 0', unit=' [kg/m^3]'), &
      key('nonlinear', mat%nonlinear), &
      key('tensile_strength', mat%tensile_strength, need=with, range='> 0', unit=' [Pa]'), &
      key('compressive_strength', mat%compressive_strength, need=with, range='> 0', &
          unit=' [Pa]'), &
      key('shear_strength', mat%shear_strength, need=with, range='> 0', unit=' [Pa]'), &
      key('history_depth', mat%history_depth, range='>= 2', &
          unit=' (reversal points kept per spring)'), &
      key('fracture', mat%fracture), &
      key('tensile_failure_strain', mat%tensile_failure_strain), &
      key('compressive_failure_strain', mat%compressive_failure_strain), &
      key('shear_failure_strain', mat%shear_failure_strain), &
      key('fracture_energy', mat%fracture_energy), &
      key('crushing_energy', mat%crushing_energy), &
      key('shear_fracture_energy', mat%shear_fracture_energy), &
      key('softening', mat%softening, allowed='linear bilinear')]
    call read_group(text, g, keys, label, try_material, chunk, stat, msg)
    if (stat /= 0) return
    call parse_material(chunk, mat, stat, iomsg)
    call check_literals(text, g, keys, label, stat, msg)
    ! (history_depth within its range even where no spring reads it: an out-of-range value is
    ! a mistake either way)
    if (stat == 0) call check_values(keys, 'e nu density history_depth', label, stat, msg)
    if (stat /= 0) return
    if (mat%nonlinear) then
      call check_values(keys, 'tensile_strength compressive_strength shear_strength', label, &
                        stat, msg)
    ! strengths without nonlinear = .true. or fracture = .true. would be silently ignored
    else if (mat%fracture) then
      continue
    else if (mat%tensile_strength /= unset_real) then
      call bad(label, 'tensile_strength', rtoa(mat%tensile_strength), &
               'is used only with nonlinear = .true. or fracture = .true.', stat, msg)
    else if (mat%compressive_strength /= unset_real) then
      call bad(label, 'compressive_strength', rtoa(mat%compressive_strength), &
               'is used only with nonlinear = .true. or fracture = .true.', stat, msg)
    else if (mat%shear_strength /= unset_real) then
      call bad(label, 'shear_strength', rtoa(mat%shear_strength), &
               'is used only with nonlinear = .true. or fracture = .true.', stat, msg)
    end if
    if (stat == 0) call check_fracture_keys(mat, label, stat, msg)
    if (stat == 0 .and. len_trim(mat%softening) > 0) then
      if (mat%fracture) then
        call check_values(keys, 'softening', label, stat, msg)
      else
        call bad(label, 'softening', "'"//trim(mat%softening)//"'", 'is used only with '// &
                 'fracture = .true.', stat, msg)
      end if
    end if
    if (len_trim(mat%softening) == 0) mat%softening = 'linear'
  end subroutine read_material

  integer function try_material(part, iomsg) result(ios)
    character(len=line_len), intent(in) :: part(:)
    character(len=256), intent(out) :: iomsg
    type(material_config_t) :: c
    call parse_material(part, c, ios, iomsg)
  end function try_material

  ! ------------------------------------------------------------------------------ &damping
  subroutine parse_damping(chunk, cfg, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: ios
    character(len=256), intent(out) :: iomsg
    character(len=12) :: kind
    real(wp) :: ratio, frequency, alpha, beta
    real(wp) :: cap_frequency
    namelist /damping/ kind, ratio, frequency, alpha, beta, cap_frequency
    kind = 'none'; ratio = unset_real; frequency = unset_real
    alpha = unset_real; beta = unset_real; cap_frequency = unset_real
    iomsg = ''
    read(chunk, nml=damping, iostat=ios, iomsg=iomsg)
    cfg%damping%kind = lower(kind); cfg%damping%ratio = ratio
    cfg%damping%frequency = frequency; cfg%damping%alpha = alpha; cfg%damping%beta = beta
    cfg%damping%cap_frequency = cap_frequency
  end subroutine parse_damping

  !> Check, parse and validate group g (&damping) of the input into the configuration.
  subroutine read_damping(text, g, cfg, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(config_t), intent(inout), target :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=256) :: iomsg
    character(len=*), parameter :: label = '&damping'
    type(key_t) :: keys(6)
    logical :: by_ratio, by_coeff
    associate(d => cfg%damping)
      keys = [key('kind', d%kind, allowed='none mass stiffness rayleigh capped'), &
        key('ratio', d%ratio, range='[0, 1)'), &
        key('frequency', d%frequency, need=' with ratio [Hz]', range='> 0', unit=' [Hz]'), &
        key('alpha', d%alpha, range='>= 0', unit=' [1/s]'), &
        key('beta', d%beta, range='>= 0', unit=' [s]'), &
        key('cap_frequency', d%cap_frequency, need=" for kind = 'capped' [Hz]", range='> 0', &
            unit=' [Hz]')]
    end associate
    call read_group(text, g, keys, label, try_damping, chunk, stat, msg)
    if (stat /= 0) return
    call parse_damping(chunk, cfg, stat, iomsg)
    call check_literals(text, g, keys, label, stat, msg)
    if (stat == 0) call check_values(keys, 'kind', label, stat, msg)
    if (stat /= 0) return
    associate(d => cfg%damping)
      by_ratio = d%ratio /= unset_real .or. d%frequency /= unset_real
      by_coeff = d%alpha /= unset_real .or. d%beta /= unset_real
      if (trim(d%kind) == 'none') then
        if (by_ratio .or. by_coeff) call bad(label, 'kind', "'none'", &
          'takes no ratio, frequency, alpha or beta', stat, msg)
        d%alpha = 0.0_wp; d%beta = 0.0_wp
      else if (trim(d%kind) /= 'capped' .and. d%cap_frequency /= unset_real) then
        call bad(label, 'cap_frequency', rtoa(d%cap_frequency), "needs kind = 'capped'", &
                 stat, msg)
      else if (trim(d%kind) == 'capped') then
        call check_values(keys, 'cap_frequency', label, stat, msg)
      end if
      if (stat == 0 .and. trim(d%kind) /= 'none') call check_rates()
      if (d%ratio == unset_real) d%ratio = 0.0_wp
      if (d%frequency == unset_real) d%frequency = 0.0_wp
      if (d%cap_frequency == unset_real) d%cap_frequency = 0.0_wp
    end associate
  contains
    !> Check ratio and frequency, or alpha and beta, and find alpha and beta from them.
    subroutine check_rates()
      real(wp) :: omega
      associate(d => cfg%damping)
        if (by_coeff .and. trim(d%kind) /= 'rayleigh') then
          call bad(label, 'kind', "'"//trim(d%kind)//"'", &
                   "is given by ratio and frequency; alpha, beta need kind = 'rayleigh'", stat, msg)
        else if (by_coeff .and. by_ratio) then
          call bad(label, 'alpha', rtoa(d%alpha), &
                   'give either ratio and frequency, or alpha and beta, not both', stat, msg)
        else if (by_coeff) then
          if (d%alpha == unset_real) d%alpha = 0.0_wp
          if (d%beta == unset_real) d%beta = 0.0_wp
          call check_values(keys, 'alpha beta', label, stat, msg)
        else if (d%ratio == unset_real) then
          call bad(label, 'ratio', '(not given)', "is required for kind = '"//trim(d%kind)// &
                   "'", stat, msg)
        else
          call check_values(keys, 'ratio frequency', label, stat, msg)
          if (stat /= 0) return
          omega = 2.0_wp*3.141592653589793_wp*d%frequency
          select case (trim(d%kind))
          case ('mass')
            d%alpha = 2.0_wp*d%ratio*omega; d%beta = 0.0_wp
          case ('stiffness')
            d%alpha = 0.0_wp; d%beta = 2.0_wp*d%ratio/omega
          case ('rayleigh')
            d%alpha = d%ratio*omega; d%beta = d%ratio/omega
          case ('capped')
            ! beta follows from ratio, frequency and cap_frequency in the model
            d%alpha = 0.0_wp; d%beta = 0.0_wp
          end select
        end if
      end associate
    end subroutine check_rates
  end subroutine read_damping

  integer function try_damping(part, iomsg) result(ios)
    character(len=line_len), intent(in) :: part(:)
    character(len=256), intent(out) :: iomsg
    type(config_t) :: c
    call parse_damping(part, c, ios, iomsg)
  end function try_damping

end module iem_input_body
