!> Readers of the groups that describe the body: &geometry, &material and &damping.
module iem_input_body
  use iem_kinds, only: wp
  use iem_constants, only: unset_real, unset_int
  use iem_strings, only: itoa, rtoa, lower
  use iem_config, only: config_t, material_config_t, name_len, path_len
  use iem_namelist_text, only: nml_text_t, line_len
  use iem_input_checks, only: bad, check_keys, read_error, check_reals, check_logicals, &
                              check_strings, given
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
    character(len=:), allocatable, intent(out) :: iomsg
    !> Whether image_levels or image_materials has an empty value before a given one.
    logical, intent(out), optional :: gaps
    real(wp) :: length, height, thickness, cell_size
    integer :: nx, ny, image_levels(max_levels), nl, nm
    character(len=8) :: plane, cell, pieces
    character(len=name_len) :: background, image_materials(max_levels)
    character(len=path_len) :: image
    character(len=256) :: m
    namelist /geometry/ length, height, thickness, nx, ny, cell_size, plane, cell, &
      background, image, image_levels, image_materials, pieces
    length = unset_real; height = unset_real; thickness = cfg%geometry%thickness
    nx = 0; ny = 0; cell_size = 0.0_wp; plane = cfg%geometry%plane; cell = cfg%geometry%cell
    background = ''; image = ''; image_levels = unset_int; image_materials = unset_name
    pieces = cfg%geometry%pieces
    m = ''
    read(chunk, nml=geometry, iostat=ios, iomsg=m)
    iomsg = trim(m)
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
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg
    character(len=*), parameter :: label = '&geometry'
    real(wp) :: nn
    logical :: gaps, has_image
    call check_keys(text, g, [character(len=15) :: 'length', 'height', 'thickness', 'nx', 'ny', &
      'cell_size', 'plane', 'cell', 'background', 'image', 'image_levels', 'image_materials', &
      'pieces'], label, stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_geometry(chunk, cfg, stat, iomsg, gaps)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, try_geometry, msg)
      stat = 1
      return
    end if
    call check_strings(text, g, label, [character(len=15) :: 'plane', 'cell', 'background', &
      'image', 'image_materials', 'pieces'], [8, 8, name_len, path_len, name_len, 8], stat, msg)
    if (stat /= 0) return
    call check_fill(text, g, label, cfg, gaps, stat, msg)
    if (stat /= 0) return
    if (given(text, g, 'cell_size') .and. .not. (cfg%geometry%cell_size > 0.0_wp)) then
      call bad(label, 'cell_size', rtoa(cfg%geometry%cell_size), 'must be > 0 [m] (or give '// &
               'nx, ny instead)', stat, msg)
      return
    end if
    call check_reals(text, g, label, [character(len=9) :: 'length', 'height', 'thickness', &
      'cell_size'], [cfg%geometry%length, cfg%geometry%height, cfg%geometry%thickness, &
      cfg%geometry%cell_size], stat, msg)
    if (stat /= 0) return
    has_image = len_trim(cfg%geometry%image) > 0
    associate(o => cfg%geometry)
      if (o%length == unset_real) then
        call bad(label, 'length', '(not given)', 'is required [m]', stat, msg)
      else if (.not. (o%length > 0.0_wp)) then
        call bad(label, 'length', rtoa(o%length), 'must be > 0 [m]', stat, msg)
      else if (o%height == unset_real) then
        call bad(label, 'height', '(not given)', 'is required [m]', stat, msg)
      else if (.not. (o%height > 0.0_wp)) then
        call bad(label, 'height', rtoa(o%height), 'must be > 0 [m]', stat, msg)
      else if (.not. (o%thickness > 0.0_wp)) then
        call bad(label, 'thickness', rtoa(o%thickness), 'must be > 0 [m]', stat, msg)
      else if (o%plane /= 'stress' .and. o%plane /= 'strain') then
        call bad(label, 'plane', "'"//trim(o%plane)//"'", "must be 'stress' or 'strain'", &
                 stat, msg)
      else if (o%cell /= 'paper' .and. o%cell /= 'bending') then
        call bad(label, 'cell', "'"//trim(o%cell)//"'", "must be 'paper' or 'bending'", &
                 stat, msg)
      else if (o%cell_size /= 0.0_wp .and. (o%nx /= 0 .or. o%ny /= 0)) then
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

  integer function try_geometry(part) result(ios)
    character(len=line_len), intent(in) :: part(:)
    type(config_t) :: c
    character(len=:), allocatable :: m
    call parse_geometry(part, c, ios, m)
  end function try_geometry

  !> Check what fills the grid: pieces, and the image variables (only with image; levels
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
      if (o%pieces /= 'warn' .and. o%pieces /= 'allow' .and. o%pieces /= 'one') then
        call bad(label, 'pieces', "'"//trim(o%pieces)//"'", "must be 'warn', 'allow' or 'one'", &
                 stat, msg)
        return
      end if
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
    character(len=:), allocatable, intent(out) :: iomsg
    character(len=name_len) :: name
    real(wp) :: e, nu, density, tensile_strength, compressive_strength, shear_strength
    logical :: nonlinear
    integer :: history_depth
    character(len=256) :: m
    namelist /material/ name, e, nu, density, nonlinear, tensile_strength, &
      compressive_strength, shear_strength, history_depth
    name = ''; e = unset_real; nu = unset_real; density = unset_real
    nonlinear = mat%nonlinear; history_depth = mat%history_depth
    tensile_strength = unset_real; compressive_strength = unset_real
    shear_strength = unset_real
    m = ''
    read(chunk, nml=material, iostat=ios, iomsg=m)
    iomsg = trim(m)
    mat%name = name
    mat%young = e; mat%poisson = nu; mat%density = density
    mat%nonlinear = nonlinear; mat%history_depth = history_depth
    mat%tensile_strength = tensile_strength
    mat%compressive_strength = compressive_strength
    mat%shear_strength = shear_strength
  end subroutine parse_material

  !> Check, parse and validate group g (one &material, called label in messages) into mat;
  !> the name is checked against the other materials later (iem_input_scene).
  subroutine read_material(text, g, label, mat, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    character(len=*), intent(in) :: label
    type(material_config_t), intent(inout) :: mat
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg
    call check_keys(text, g, [character(len=20) :: 'name', 'e', 'nu', 'density', 'nonlinear', &
      'tensile_strength', 'compressive_strength', 'shear_strength', 'history_depth'], label, &
      stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_material(chunk, mat, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, try_material, msg)
      stat = 1
      return
    end if
    call check_strings(text, g, label, ['name'], [name_len], stat, msg)
    if (stat /= 0) return
    associate(m => mat)
      call check_reals(text, g, label, [character(len=20) :: 'e', 'nu', 'density', &
        'tensile_strength', 'compressive_strength', 'shear_strength'], [m%young, m%poisson, &
        m%density, m%tensile_strength, m%compressive_strength, m%shear_strength], stat, msg)
    end associate
    if (stat == 0) call check_logicals(text, g, label, ['nonlinear'], stat, msg)
    if (stat /= 0) return
    associate(m => mat)
      if (m%young == unset_real) then
        call bad(label, 'E', '(not given)', "is required: Young's modulus [Pa]", stat, msg)
      else if (.not. (m%young > 0.0_wp)) then
        call bad(label, 'E', rtoa(m%young), 'must be > 0 [Pa]', stat, msg)
      else if (m%poisson == unset_real) then
        call bad(label, 'nu', '(not given)', "is required: Poisson's ratio", stat, msg)
      else if (.not. (m%poisson > -1.0_wp .and. m%poisson < 0.5_wp)) then
        call bad(label, 'nu', rtoa(m%poisson), 'must be in (-1, 0.5)', stat, msg)
      else if (m%density == unset_real) then
        call bad(label, 'density', '(not given)', 'is required [kg/m^3]', stat, msg)
      else if (.not. (m%density > 0.0_wp)) then
        call bad(label, 'density', rtoa(m%density), 'must be > 0 [kg/m^3]', stat, msg)
      else if (m%nonlinear) then
        call check_strength('tensile_strength', m%tensile_strength)
        if (stat == 0) call check_strength('compressive_strength', m%compressive_strength)
        if (stat == 0) call check_strength('shear_strength', m%shear_strength)
        if (stat == 0 .and. m%history_depth < 2) call bad(label, 'history_depth', &
          itoa(m%history_depth), 'must be >= 2 (reversal points kept per spring)', stat, msg)
      else
        ! strengths without nonlinear = .true. would be silently ignored
        if (m%tensile_strength /= unset_real) then
          call bad(label, 'tensile_strength', rtoa(m%tensile_strength), &
                   'is used only with nonlinear = .true.', stat, msg)
        else if (m%compressive_strength /= unset_real) then
          call bad(label, 'compressive_strength', rtoa(m%compressive_strength), &
                   'is used only with nonlinear = .true.', stat, msg)
        else if (m%shear_strength /= unset_real) then
          call bad(label, 'shear_strength', rtoa(m%shear_strength), &
                   'is used only with nonlinear = .true.', stat, msg)
        end if
      end if
    end associate
  contains
    subroutine check_strength(name, value)
      character(len=*), intent(in) :: name
      real(wp), intent(in) :: value
      if (value == unset_real) then
        call bad(label, name, '(not given)', 'is required with nonlinear = .true. [Pa]', stat, msg)
      else if (.not. (value > 0.0_wp)) then
        call bad(label, name, rtoa(value), 'must be > 0 [Pa]', stat, msg)
      end if
    end subroutine check_strength
  end subroutine read_material

  integer function try_material(part) result(ios)
    character(len=line_len), intent(in) :: part(:)
    type(material_config_t) :: c
    character(len=:), allocatable :: m
    call parse_material(part, c, ios, m)
  end function try_material

  ! ------------------------------------------------------------------------------ &damping
  subroutine parse_damping(chunk, cfg, ios, iomsg)
    character(len=line_len), intent(in) :: chunk(:)
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: ios
    character(len=:), allocatable, intent(out) :: iomsg
    character(len=12) :: kind
    real(wp) :: ratio, frequency, alpha, beta
    character(len=256) :: m
    real(wp) :: cap_frequency
    namelist /damping/ kind, ratio, frequency, alpha, beta, cap_frequency
    kind = 'none'; ratio = unset_real; frequency = unset_real
    alpha = unset_real; beta = unset_real; cap_frequency = unset_real
    m = ''
    read(chunk, nml=damping, iostat=ios, iomsg=m)
    iomsg = trim(m)
    cfg%damping%kind = lower(kind); cfg%damping%ratio = ratio
    cfg%damping%frequency = frequency; cfg%damping%alpha = alpha; cfg%damping%beta = beta
    cfg%damping%cap_frequency = cap_frequency
  end subroutine parse_damping

  !> Check, parse and validate group g (&damping) of the input into the configuration.
  subroutine read_damping(text, g, cfg, stat, msg)
    type(nml_text_t), intent(in) :: text
    integer, intent(in) :: g
    type(config_t), intent(inout) :: cfg
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=line_len), allocatable :: chunk(:)
    character(len=:), allocatable :: iomsg
    character(len=*), parameter :: label = '&damping'
    real(wp) :: omega
    logical :: by_ratio, by_coeff
    call check_keys(text, g, [character(len=13) :: 'kind', 'ratio', 'frequency', 'alpha', &
      'beta', 'cap_frequency'], label, stat, msg)
    if (stat /= 0) return
    call text%chunk(g, chunk)
    call parse_damping(chunk, cfg, stat, iomsg)
    if (stat /= 0) then
      call read_error(text, g, label, iomsg, chunk, try_damping, msg)
      stat = 1
      return
    end if
    call check_strings(text, g, label, ['kind'], [12], stat, msg)
    if (stat /= 0) return
    associate(d => cfg%damping)
      call check_reals(text, g, label, [character(len=13) :: 'ratio', 'frequency', 'alpha', &
        'beta', 'cap_frequency'], [d%ratio, d%frequency, d%alpha, d%beta, d%cap_frequency], &
        stat, msg)
    end associate
    if (stat /= 0) return
    associate(d => cfg%damping)
      by_ratio = d%ratio /= unset_real .or. d%frequency /= unset_real
      by_coeff = d%alpha /= unset_real .or. d%beta /= unset_real
      select case (trim(d%kind))
      case ('none')
        if (by_ratio .or. by_coeff) call bad(label, 'kind', "'none'", &
          'takes no ratio, frequency, alpha or beta', stat, msg)
      case ('mass', 'stiffness', 'rayleigh', 'capped')
        if (trim(d%kind) /= 'capped' .and. d%cap_frequency /= unset_real) then
          call bad(label, 'cap_frequency', rtoa(d%cap_frequency), &
                   "needs kind = 'capped'", stat, msg)
        else if (trim(d%kind) == 'capped' .and. d%cap_frequency == unset_real) then
          call bad(label, 'cap_frequency', '(not given)', &
                   "is required for kind = 'capped' [Hz]", stat, msg)
        else if (trim(d%kind) == 'capped' .and. .not. (d%cap_frequency > 0.0_wp)) then
          call bad(label, 'cap_frequency', rtoa(d%cap_frequency), 'must be > 0 [Hz]', &
                   stat, msg)
        else if (by_coeff .and. trim(d%kind) /= 'rayleigh') then
          call bad(label, 'kind', "'"//trim(d%kind)//"'", &
                   "is given by ratio and frequency; alpha, beta need kind = 'rayleigh'", stat, msg)
        else if (by_coeff .and. by_ratio) then
          call bad(label, 'alpha', rtoa(d%alpha), &
                   'give either ratio and frequency, or alpha and beta, not both', stat, msg)
        else if (by_coeff) then
          if (d%alpha == unset_real) d%alpha = 0.0_wp
          if (d%beta == unset_real) d%beta = 0.0_wp
          if (.not. (d%alpha >= 0.0_wp)) then
            call bad(label, 'alpha', rtoa(d%alpha), 'must be >= 0 [1/s]', stat, msg)
          else if (.not. (d%beta >= 0.0_wp)) then
            call bad(label, 'beta', rtoa(d%beta), 'must be >= 0 [s]', stat, msg)
          end if
        else if (d%ratio == unset_real) then
          call bad(label, 'ratio', '(not given)', 'is required for kind = '''// &
                   trim(d%kind)//'''', stat, msg)
        else if (.not. (d%ratio >= 0.0_wp .and. d%ratio < 1.0_wp)) then
          call bad(label, 'ratio', rtoa(d%ratio), 'must be in [0, 1)', stat, msg)
        else if (d%frequency == unset_real) then
          call bad(label, 'frequency', '(not given)', 'is required with ratio [Hz]', stat, msg)
        else if (.not. (d%frequency > 0.0_wp)) then
          call bad(label, 'frequency', rtoa(d%frequency), 'must be > 0 [Hz]', stat, msg)
        else
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
      case default
        call bad(label, 'kind', "'"//trim(d%kind)//"'", &
                 "must be 'none', 'mass', 'stiffness', 'rayleigh' or 'capped'", stat, msg)
      end select
      if (d%kind == 'none') then
        d%alpha = 0.0_wp; d%beta = 0.0_wp
      end if
      if (d%ratio == unset_real) d%ratio = 0.0_wp
      if (d%frequency == unset_real) d%frequency = 0.0_wp
      if (d%cap_frequency == unset_real) d%cap_frequency = 0.0_wp
    end associate
  end subroutine read_damping

  integer function try_damping(part) result(ios)
    character(len=line_len), intent(in) :: part(:)
    type(config_t) :: c
    character(len=:), allocatable :: m
    call parse_damping(part, c, ios, m)
  end function try_damping

end module iem_input_body
