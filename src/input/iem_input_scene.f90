!> Checks of the scene once every group is read: material names (distinct, reserved words),
!> the nonlinear materials against the cell law, and every reference by name resolved to an
!> index: the background, the image's materials, each shape's material and the shapes that
!> node sets name (docs/input.md, "Materials and shapes").
module iem_input_scene
  use iem_strings, only: itoa, lower
  use iem_config, only: config_t, node_set_spec_t
  use iem_input_checks, only: bad
  use iem_input_shapes, only: valid_name
  implicit none
  private
  public :: resolve_scene, material_index

  !> Length of a group's label in messages ('&material #12 (line 345)').
  integer, parameter, public :: label_len = 48

contains

  !> The index of the material that ref names: 0 for 'void' (any case), k for materials(k),
  !> 1 for 'default' when the only material has no name, -1 when ref names none.
  pure integer function material_index(cfg, ref) result(k)
    type(config_t), intent(in) :: cfg
    character(len=*), intent(in) :: ref
    integer :: j
    k = -1
    if (lower(trim(ref)) == 'void') then
      k = 0
    else if (size(cfg%materials) == 1 .and. len_trim(cfg%materials(1)%name) == 0) then
      if (trim(ref) == 'default') k = 1
    else if (len_trim(ref) > 0) then
      do j = 1, size(cfg%materials)
        if (cfg%materials(j)%name == ref) then
          k = j
          return
        end if
      end do
    end if
  end function material_index

  !> The names a material may be referred to by, for messages: 'void', 'steel', ...
  function known_materials(cfg) result(list)
    type(config_t), intent(in) :: cfg
    character(len=:), allocatable :: list
    integer :: j
    list = "'void'"
    if (size(cfg%materials) == 1 .and. len_trim(cfg%materials(1)%name) == 0) then
      list = list//", 'default' (the one &material, which has no name)"
      return
    end if
    do j = 1, size(cfg%materials)
      list = list//", '"//trim(cfg%materials(j)%name)//"'"
    end do
  end function known_materials

  !> Check the materials and resolve every name of the scene; labels name the groups
  !> (material_labels(k) is '&material #k (line N)', or '&material' when there is one).
  subroutine resolve_scene(cfg, material_labels, shape_labels, bc_labels, load_labels, &
                           stat, msg)
    type(config_t), intent(inout) :: cfg
    character(len=label_len), intent(in) :: material_labels(:), shape_labels(:), &
      bc_labels(:), load_labels(:)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: k, j, first_nl
    character(len=:), allocatable :: label
    stat = 0
    msg = ''
    ! names of the materials
    do k = 1, size(cfg%materials)
      label = trim(material_labels(k))
      associate(name => cfg%materials(k)%name)
        if (len_trim(name) == 0) then
          if (size(cfg%materials) > 1) then
            call bad(label, 'name', '(not given)', 'is required when there are several '// &
                     '&material groups ('//itoa(size(cfg%materials))//'): each needs its '// &
                     'own name', stat, msg)
            return
          end if
        else if (lower(trim(name)) == 'void' .or. lower(trim(name)) == 'default' .or. &
                 lower(trim(name)) == 'crack') then
          call bad(label, 'name', "'"//trim(name)//"'", "is reserved ('void' means no "// &
                   "material, 'default' the one unnamed material, 'crack' a pre-cut shape)", &
                   stat, msg)
          return
        else if (.not. valid_name(name)) then
          call bad(label, 'name', "'"//trim(name)//"'", 'may hold only letters, digits, '// &
                   '_ - and .', stat, msg)
          return
        end if
        do j = 1, k - 1
          if (cfg%materials(j)%name == name) then
            call bad(label, 'name', "'"//trim(name)//"'", 'is already the name of '// &
                     trim(material_labels(j)), stat, msg)
            return
          end if
        end do
      end associate
    end do
    ! nonlinear materials: the paper's cell, one history depth
    first_nl = 0
    do k = 1, size(cfg%materials)
      associate(m => cfg%materials(k))
        if (.not. m%nonlinear) cycle
        if (cfg%geometry%cell /= 'paper') then
          call bad('&geometry', 'cell', "'"//trim(cfg%geometry%cell)//"'", 'cannot be used '// &
                   'with nonlinear springs ('//trim(material_labels(k))//' has nonlinear = '// &
                   ".true.): use cell = 'paper'", stat, msg)
          return
        end if
        if (first_nl == 0) then
          first_nl = k
        else if (m%history_depth /= cfg%materials(first_nl)%history_depth) then
          call bad(trim(material_labels(k)), 'history_depth', itoa(m%history_depth), &
                   'differs from history_depth = '// &
                   itoa(cfg%materials(first_nl)%history_depth)//' of '// &
                   trim(material_labels(first_nl))//': every nonlinear material keeps the '// &
                   'same number of reversal points', stat, msg)
          return
        end if
      end associate
    end do
    ! what fills the grid
    associate(o => cfg%geometry)
      if (len_trim(o%background) == 0) then
        o%background_id = 1
      else
        o%background_id = material_index(cfg, o%background)
        if (o%background_id < 0) then
          call unknown('&geometry', 'background', o%background)
          return
        end if
      end if
      do k = 1, size(o%image_materials)
        o%image_material_ids(k) = material_index(cfg, o%image_materials(k))
        if (o%image_material_ids(k) < 0) then
          call unknown('&geometry', 'image_materials', o%image_materials(k))
          return
        end if
      end do
    end associate
    do k = 1, size(cfg%shapes)
      label = trim(shape_labels(k))
      associate(sh => cfg%shapes(k))
        sh%crack = lower(trim(sh%material)) == 'crack'
        sh%material_id = 0
        if (.not. sh%crack) sh%material_id = material_index(cfg, sh%material)
        if (sh%material_id < 0) then
          call unknown(label, 'material', sh%material)
          return
        end if
        if (len_trim(sh%name) == 0) cycle
        do j = 1, k - 1
          if (cfg%shapes(j)%name == sh%name) then
            call bad(label, 'name', "'"//trim(sh%name)//"'", 'is already the name of '// &
                     trim(shape_labels(j)), stat, msg)
            return
          end if
        end do
      end associate
    end do
    if (cfg%geometry%background_id == 0 .and. len_trim(cfg%geometry%image) == 0 .and. &
        .not. any(cfg%shapes(:)%material_id > 0)) then
      call bad('&geometry', 'background', "'void'", 'leaves no material: give an image or '// &
               'a &shape with a material', stat, msg)
      return
    end if
    ! the shapes that node sets name
    do k = 1, size(cfg%bcs)
      call resolve_set(cfg%bcs(k)%set, trim(bc_labels(k)))
      if (stat /= 0) return
    end do
    do k = 1, size(cfg%loads)
      call resolve_set(cfg%loads(k)%set, trim(load_labels(k)))
      if (stat /= 0) return
    end do

  contains

    subroutine unknown(label, var, ref)
      character(len=*), intent(in) :: label, var, ref
      call bad(label, var, "'"//trim(ref)//"'", 'is not a material: known are '// &
               known_materials(cfg), stat, msg)
    end subroutine unknown

    subroutine resolve_set(set, label)
      type(node_set_spec_t), intent(inout) :: set
      character(len=*), intent(in) :: label
      character(len=:), allocatable :: list
      integer :: j
      if (set%where /= 'shape') return
      set%shape_id = 0
      do j = 1, size(cfg%shapes)
        if (len_trim(cfg%shapes(j)%name) > 0 .and. cfg%shapes(j)%name == set%shape) then
          set%shape_id = j
          return
        end if
      end do
      list = ''
      do j = 1, size(cfg%shapes)
        if (len_trim(cfg%shapes(j)%name) == 0) cycle
        if (len(list) > 0) list = list//', '
        list = list//"'"//trim(cfg%shapes(j)%name)//"'"
      end do
      if (len(list) == 0) list = 'none (give the &shape a name)'
      call bad(label, 'shape', "'"//trim(set%shape)//"'", 'is not the name of a &shape; '// &
               'named shapes: '//list, stat, msg)
    end subroutine resolve_set
  end subroutine resolve_scene
end module iem_input_scene
